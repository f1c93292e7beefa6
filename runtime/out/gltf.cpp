// glTF 2.0 export (see gltf.h), built as a tinygltf::Model and serialised by tinygltf (the one
// translation unit that compiles its implementation).
#include "runtime/out/gltf.h"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <system_error>
#include <vector>

#include "runtime/core/atomic_file.h"
#include "runtime/out/bvh.h"

#define TINYGLTF_IMPLEMENTATION
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <tiny_gltf.h>

namespace mocap::out {

namespace {

using Eigen::Quaterniond;
using Eigen::Vector3d;

constexpr std::size_t ix(int i) { return static_cast<std::size_t>(i); }

// Appends `values` (count elements of `type`, float components) to buffer 0 as its own
// buffer view and accessor; returns the accessor index.
int add_accessor(tinygltf::Model& model, const std::vector<float>& values, int type,
                 std::size_t count, bool with_min_max = false) {
  std::vector<unsigned char>& data = model.buffers[0].data;
  tinygltf::BufferView view;
  view.buffer = 0;
  view.byteOffset = data.size();
  view.byteLength = values.size() * sizeof(float);
  data.resize(data.size() + view.byteLength);
  std::memcpy(data.data() + view.byteOffset, values.data(), view.byteLength);
  model.bufferViews.push_back(view);
  tinygltf::Accessor a;
  a.bufferView = static_cast<int>(model.bufferViews.size() - 1);
  a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
  a.type = type;
  a.count = count;
  if (with_min_max && !values.empty()) {  // scalars only (the key times)
    a.minValues = {static_cast<double>(values.front())};
    a.maxValues = {static_cast<double>(values.back())};
  }
  model.accessors.push_back(a);
  return static_cast<int>(model.accessors.size() - 1);
}

std::vector<double> to_doubles(const Vector3d& v) { return {v.x(), v.y(), v.z()}; }

// The bone's rest position in the person's node (all rest rotations are the identity).
PerBone<Vector3d> rest_positions(const PersonAnimation& person) {
  PerBone<Vector3d> at;
  for (int b = 0; b < kHumanBoneCount; ++b) {
    const int p = human_bones()[ix(b)].parent;
    at[ix(b)] = p < 0 ? to_y_up(person.poses.front().hips_m)
                      : Vector3d(at[ix(p)] + to_y_up(person.shape.offset_m[ix(b)]));
  }
  return at;
}

// Column-major 4x4 inverse bind matrices: translations by minus the rest positions.
std::vector<float> inverse_bind_matrices(const PerBone<Vector3d>& rest) {
  std::vector<float> m;
  for (const Vector3d& p : rest) {
    const float t[3] = {static_cast<float>(-p.x()), static_cast<float>(-p.y()),
                        static_cast<float>(-p.z())};
    m.insert(m.end(), {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, t[0], t[1], t[2], 1});
  }
  return m;
}

// Adds the person's nodes and skin; returns the index of its first bone node (bone b is
// node first + b) and appends the person node to the scene.
int add_person_nodes(tinygltf::Model& model, const PersonAnimation& person) {
  const std::string name = "person_" + std::to_string(person.person_id);
  const int person_node = static_cast<int>(model.nodes.size());
  const int first = person_node + 1;
  tinygltf::Node root;
  root.name = name;
  root.children = {first + kHips};
  model.nodes.push_back(root);
  const PerBone<Vector3d> rest = rest_positions(person);
  tinygltf::Skin skin;
  skin.name = name;
  skin.skeleton = person_node;
  for (int b = 0; b < kHumanBoneCount; ++b) {
    tinygltf::Node n;
    n.name = std::string(human_bones()[ix(b)].name);
    const int p = human_bones()[ix(b)].parent;
    n.translation = to_doubles(p < 0 ? rest[ix(b)] : Vector3d(rest[ix(b)] - rest[ix(p)]));
    for (int c = b + 1; c < kHumanBoneCount; ++c) {
      if (human_bones()[ix(c)].parent == b) n.children.push_back(first + c);
    }
    model.nodes.push_back(n);
    skin.joints.push_back(first + b);
  }
  skin.inverseBindMatrices =
      add_accessor(model, inverse_bind_matrices(rest), TINYGLTF_TYPE_MAT4, ix(kHumanBoneCount));
  model.skins.push_back(skin);
  model.scenes[0].nodes.push_back(person_node);
  return first;
}

void add_channel(tinygltf::Animation& take, int node, const char* path, int input, int output) {
  tinygltf::AnimationSampler s;
  s.input = input;
  s.output = output;
  s.interpolation = "LINEAR";
  take.samplers.push_back(s);
  tinygltf::AnimationChannel c;
  c.sampler = static_cast<int>(take.samplers.size() - 1);
  c.target_node = node;
  c.target_path = path;
  take.channels.push_back(c);
}

// Bone b's rotation keys, xyzw, each on the same hemisphere as the one before (so that
// component-wise interpolation, as in Blender, stays short).
std::vector<float> rotation_keys(const PersonAnimation& person, int b) {
  std::vector<float> keys;
  keys.reserve(person.poses.size() * 4);
  Quaterniond last = Quaterniond::Identity();
  for (const HumanoidPose& pose : person.poses) {
    Quaterniond q = to_y_up(pose.local[ix(b)]);
    if (q.dot(last) < 0) q.coeffs() = -q.coeffs();
    last = q;
    for (int i = 0; i < 4; ++i) keys.push_back(static_cast<float>(q.coeffs()[i]));  // x y z w
  }
  return keys;
}

void add_person_channels(tinygltf::Model& model, tinygltf::Animation& take,
                         const PersonAnimation& person, int first_bone_node, int times) {
  const std::size_t n = person.poses.size();
  std::vector<float> hips;
  hips.reserve(n * 3);
  for (const HumanoidPose& pose : person.poses) {
    const Vector3d p = to_y_up(pose.hips_m);
    hips.insert(hips.end(),
                {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())});
  }
  add_channel(take, first_bone_node + kHips, "translation", times,
              add_accessor(model, hips, TINYGLTF_TYPE_VEC3, n));
  for (int b = 0; b < kHumanBoneCount; ++b) {
    add_channel(take, first_bone_node + b, "rotation", times,
                add_accessor(model, rotation_keys(person, b), TINYGLTF_TYPE_VEC4, n));
  }
}

tinygltf::Model build_model(const Animation& anim) {
  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "mocap-box";
  model.buffers.resize(1);
  model.scenes.resize(1);
  model.defaultScene = 0;
  std::vector<float> t(ix(anim.frame_count));
  for (std::size_t f = 0; f < t.size(); ++f) {
    t[f] = static_cast<float>(static_cast<double>(f) / anim.frame_rate_hz);
  }
  const int times = add_accessor(model, t, TINYGLTF_TYPE_SCALAR, t.size(), true);
  tinygltf::Animation take;
  take.name = "take";
  for (const PersonAnimation& person : anim.persons) {
    add_person_channels(model, take, person, add_person_nodes(model, person), times);
  }
  model.animations.push_back(take);
  return model;
}

Status check_animation(const Animation& anim, const std::filesystem::path& file, bool binary) {
  const std::string name = file.string();
  const std::string want = binary ? ".glb" : ".gltf";
  if (file.extension() != want) {
    return Error(ErrorCode::kInvalidArgument,
                 name + ": a " + (binary ? "binary" : "text") + " glTF file must end in " + want);
  }
  if (anim.persons.empty()) {
    return Error(ErrorCode::kInvalidArgument, name + ": the take has no person to export");
  }
  for (const PersonAnimation& person : anim.persons) {
    if (Status s = check_person_animation(anim, person); !s.ok()) {
      return s.error().with_context(name);
    }
  }
  return Status();
}

}  // namespace

Status GltfOptions::validate() const { return Status(); }

Status write_gltf(const Animation& anim, const GltfOptions& options,
                  const std::filesystem::path& file) {
  if (Status s = options.validate(); !s.ok()) return s.error().with_context(file.string());
  if (Status s = check_animation(anim, file, options.binary); !s.ok()) return s;
  try {
    const tinygltf::Model model = build_model(anim);
    std::ostringstream text;
    tinygltf::TinyGLTF writer;
    if (!writer.WriteGltfSceneToStream(&model, text, false, options.binary)) {
      return Error(ErrorCode::kInternal, file.string() + ": tinygltf could not serialise the take");
    }
    return write_file_atomically(file, text.str(), Durability::kDurable);
  } catch (const std::exception& e) {
    return Error(ErrorCode::kInternal, file.string() + ": glTF export failed: " + e.what());
  }
}

}  // namespace mocap::out
