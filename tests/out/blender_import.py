# Imports an exported BVH or glTF file into Blender with its built-in importers and writes, for
# the requested frames of the take, every armature's bone head world positions (Blender's
# world: z up, metres) to a JSON file. Run headless:
#   blender -b --factory-startup --python tests/out/blender_import.py -- \
#       (--bvh FILE [--scale 0.01] | --gltf FILE [--fps 30]) --frames 0,10,57 --out result.json
# Frame k of the take is Blender frame (the armature action's first key) + k: the BVH importer
# starts at frame 1, the glTF importer at time 0 * scene fps (so --fps sets the scene rate to
# the take's, one key per frame). Exits 1 with a message on stderr when something fails, 3 when
# this Blender cannot import the format at all (the glTF importer needs numpy: Debian's blender
# package does not pull in python3-numpy).
#
# Debian 12's Blender 3.4.1 runs on Python 3.11, where open(path, 'rU') is an error, and its BVH
# importer opens files that way; the script patches that importer's open() to drop the 'U'
# (universal newlines are the default in text mode anyway), as a user of that Blender must.
import argparse
import json
import sys
import traceback

import bpy


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="blender_import.py")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--bvh", help="BVH file (imported with the default axes)")
    src.add_argument("--gltf", help=".gltf or .glb file")
    p.add_argument("--scale", type=float, default=1.0, help="BVH global_scale (0.01 for cm)")
    p.add_argument("--fps", type=int, default=0, help="scene frame rate for the glTF import")
    p.add_argument("--frames", default="0", help="comma-separated frames of the take")
    p.add_argument("--out", required=True, help="JSON file to write")
    return p.parse_args(argv)


def clear_scene():
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj, do_unlink=True)


def patch_bvh_open():
    import builtins
    from io_anim_bvh import import_bvh

    def open_without_u(file, mode="r", *args, **kwargs):
        return builtins.open(file, mode.replace("U", ""), *args, **kwargs)

    import_bvh.open = open_without_u


def check_gltf_importer():
    try:
        import numpy  # noqa: F401  (io_scene_gltf2's importer imports it)
    except ImportError:
        sys.stderr.write("blender_import.py: this Blender's Python has no numpy, which its glTF "
                         "importer needs (Debian: apt-get install python3-numpy)\n")
        sys.exit(3)


def import_file(args):
    scene = bpy.context.scene
    if args.bvh:
        patch_bvh_open()
        result = bpy.ops.import_anim.bvh(filepath=args.bvh, global_scale=args.scale,
                                         update_scene_duration=True)
    else:
        check_gltf_importer()
        if args.fps > 0:
            scene.render.fps = args.fps
            scene.render.fps_base = 1.0
        result = bpy.ops.import_scene.gltf(filepath=args.gltf)
    if "FINISHED" not in result:
        raise RuntimeError("the importer returned %s" % (result,))


def action_keys(obj):
    """(first frame, last frame, most keys on one curve) of the object's action."""
    ad = obj.animation_data
    if ad is None or ad.action is None:
        return None, None, 0
    action = ad.action
    first, last = action.frame_range
    keys = max((len(fc.keyframe_points) for fc in action.fcurves), default=0)
    return float(first), float(last), keys


def describe_armature(obj, frames):
    first, last, keys = action_keys(obj)
    start = first if first is not None else bpy.context.scene.frame_start
    samples = {}
    for k in frames:
        frame = start + k
        whole = int(frame // 1)
        bpy.context.scene.frame_set(whole, subframe=frame - whole)
        heads = {}
        for pb in obj.pose.bones:
            heads[pb.name] = list(obj.matrix_world @ pb.head)
        samples[str(k)] = heads
    return {
        "name": obj.name,
        "bones": [b.name for b in obj.data.bones],
        "action_frame_range": [first, last],
        "action_keys": keys,
        "heads": samples,
    }


def main():
    args = parse_args()
    frames = [int(f) for f in args.frames.split(",") if f.strip()]
    clear_scene()
    import_file(args)
    scene = bpy.context.scene
    armatures = [o for o in scene.objects if o.type == "ARMATURE"]
    result = {
        "blender_version": bpy.app.version_string,
        "scene": {"frame_start": scene.frame_start, "frame_end": scene.frame_end,
                  "fps": scene.render.fps / scene.render.fps_base},
        "objects": [{"name": o.name, "type": o.type} for o in scene.objects],
        "armatures": [describe_armature(o, frames) for o in armatures],
    }
    with open(args.out, "w") as f:
        json.dump(result, f, indent=1)


try:
    main()
except SystemExit:
    raise
except Exception:
    traceback.print_exc()
    sys.stderr.write("blender_import.py failed\n")
    sys.exit(1)
