// Shared by the network kernels (one kernel per .comp; this is an include): the per-channel
// constants and the fused activation. Binding 2 holds the constants of a step as vec4 groups:
// the bias (convolutions) from 0, then the PReLU slopes from ALPHA_AT. With the two inputs
// (inputs.glsl) and the output (binding 3), a kernel uses four descriptors, at most four storage
// buffers: the spec's minimum maxPerStageDescriptorStorageBuffers.
// ACT: 0 none, 1 ReLU, 2 ReLU6, 3 PReLU, 4 sigmoid — the values of mocap::nn::Activation.
layout(constant_id = 1) const int ACT = 0;
layout(constant_id = 7) const int ALPHA_AT = 0;
layout(std430, binding = 2) readonly buffer Consts { vec4 consts[]; };

vec4 activate(vec4 v, int c4) {
  if (ACT == 1) return max(v, vec4(0.0));
  if (ACT == 2) return clamp(v, vec4(0.0), vec4(6.0));
  if (ACT == 3) return mix(v * consts[ALPHA_AT + c4], v, greaterThanEqual(v, vec4(0.0)));
  if (ACT == 4) return vec4(1.0) / (vec4(1.0) + exp(-v));
  return v;
}
