// Shared by the kernels that fuse an activation (one kernel per .comp; this is an include).
// ACT: 0 none, 1 ReLU, 2 ReLU6, 3 PReLU (slopes in `alpha`, binding 4), 4 sigmoid — the values
// of mocap::nn::Activation.
layout(constant_id = 1) const int ACT = 0;
layout(std430, binding = 4) readonly buffer Alpha { vec4 alpha[]; };

vec4 activate(vec4 v, int c4) {
  if (ACT == 1) return max(v, vec4(0.0));
  if (ACT == 2) return clamp(v, vec4(0.0), vec4(6.0));
  if (ACT == 3) return mix(v * alpha[c4], v, greaterThanEqual(v, vec4(0.0)));
  if (ACT == 4) return vec4(1.0) / (vec4(1.0) + exp(-v));
  return v;
}
