#!/usr/bin/env bash
# The first frames of pose2sim_multi through `mocap replay` (MoveNet on Vulkan, the whole
# pipeline) on lavapipe, on lavapipe planned for the Vulkan spec's minimum limits
# (MOCAP_VK_LIMITS=minimum: most network steps on storage buffers) and on SwiftShader (texel
# views of 65536 texels): the same people with the same ids and every joint within 1 mm (the
# stream's precision is 0.1 mm). A GPU result counts when both drivers agree (DEVELOPERS.md).
# Usage: replay_on_two_drivers.sh MOCAP_BIN SWIFTSHADER_ICD FRAMES
set -euo pipefail
mocap=$1 icd=$2 frames=$3
data=${MOCAP_DATA_DIR:-$(dirname "$0")/../../../shared/data}/pose2sim_multi
skip() {
  if [ "${CI:-}" = "true" ]; then echo "CI=true: $1" >&2; exit 1; fi
  echo "skipped: $1"; exit 77
}
[ -d "$data" ] || skip "no pose2sim_multi under MOCAP_DATA_DIR"
[ -f "$icd" ] || skip "no SwiftShader ICD at $icd (Debian: chromium)"
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
run() {  # run NAME ENV...
  local name=$1; shift
  local t0=$SECONDS
  env "$@" "$mocap" replay --recording "$data" --frames "$frames" --skeletons-out "$out/$name.ndjson" \
    >"$out/$name.log" 2>&1 || { tail -n 20 "$out/$name.log"; echo "$name: mocap replay failed"; exit 1; }
  echo "$name: $((SECONDS - t0)) s, $(grep -m1 -o 'on Vulkan on [^,)]*' "$out/$name.log" || echo '?')"
}
run lavapipe MOCAP_VULKAN_DEVICE=llvmpipe
run minimum MOCAP_VULKAN_DEVICE=llvmpipe MOCAP_VK_LIMITS=minimum
run swiftshader VK_ICD_FILENAMES="$icd" MOCAP_VULKAN_DEVICE=SwiftShader
python3 - "$out" "$frames" <<'PY'
import json, math, sys
out, frames = sys.argv[1], int(sys.argv[2])
def load(name):
    runs = {}
    for line in open(f"{out}/{name}.ndjson"):
        m = json.loads(line)
        runs[m["frame_id"]] = {p["id"]: {j["name"]: (j["x"], j["y"], j["z"]) for j in p["joints"]}
                               for p in m.get("persons", [])}
    return runs
ref = load("lavapipe")
ok = len(ref) == frames and all(ref[f] for f in ref)
print(f"lavapipe: {len(ref)} frames, persons per frame {[len(ref[f]) for f in sorted(ref)]}")
for name in ("minimum", "swiftshader"):
    other = load(name)
    worst, n = 0.0, 0
    for f in ref:
        if sorted(ref[f]) != sorted(other.get(f, {})):
            print(f"{name}: frame {f} ids {sorted(other.get(f, {}))}, lavapipe {sorted(ref[f])}")
            ok = False
            continue
        for pid, joints in ref[f].items():
            for jn, p in joints.items():
                worst = max(worst, math.dist(p, other[f][pid][jn])); n += 1
    print(f"{name}: {n} joints compared with lavapipe, worst {worst * 1000:.2f} mm")
    ok = ok and n > 0 and worst <= 0.001
print("two_drivers_agree=" + ("yes" if ok else "no"))
sys.exit(0 if ok else 1)
PY
