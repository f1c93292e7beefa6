#version 450
// 1x1 convolution (a GEMM over pixels): y[p][co] = act(b[co] + sum_ci x[p][ci] w[ci][co]).
// Activations are NHWC with channels in vec4 groups (C4). Each invocation computes TP pixels x
// TC vec4 output groups (spec constants; the network uses 8 x 4 = 32 vec4 accumulators, no
// shared memory, no barriers: the register-blocked shape lavapipe runs fastest, see
// docs/gpu.md). Weights are [cin4 * 4][cout4p] vec4 with cout4p = cout4 rounded up to a
// multiple of TC; the bias is [cout4p], the first constants (binding 2, activation.glsl).
#extension GL_GOOGLE_include_directive : require
layout(local_size_x_id = 0) in;
#include "activation.glsl"
#include "inputs.glsl"

layout(std430, binding = 3) writeonly buffer Out { vec4 y[]; };

layout(push_constant) uniform Params {
  int pixels;       // n * h * w
  int cin4;         // input vec4 groups read
  int in_stride4;   // vec4 groups per input pixel
  int in_offset4;   // first group read
  int cout4;        // output vec4 groups written
  int cout4p;       // weight row length (vec4)
  int out_stride4;  // vec4 groups per output pixel
  int out_offset4;  // first group written
} pc;

layout(constant_id = 2) const int TP = 8;  // pixels per invocation
layout(constant_id = 3) const int TC = 2;  // output vec4 groups per invocation
layout(constant_id = 4) const int KB = 16; // input groups per partial sum (0 = one level)

void main() {
  const int ncb = pc.cout4p / TC;
  const int gid = int(gl_GlobalInvocationID.x);
  const int cb = gid % ncb;
  const int p0 = (gid / ncb) * TP;
  if (p0 >= pc.pixels) return;
  const int co = cb * TC;
  vec4 a[TP * TC];
  int src[TP];
  for (int i = 0; i < TP; ++i) {
    for (int j = 0; j < TC; ++j) a[i * TC + j] = consts[co + j];
    src[i] = min(p0 + i, pc.pixels - 1) * pc.in_stride4 + pc.in_offset4;
  }
  int wr = co;
  const int kb = KB > 0 ? KB : pc.cin4;
  for (int c0 = 0; c0 < pc.cin4; c0 += kb) {
    vec4 s[TP * TC];
    for (int i = 0; i < TP * TC; ++i) s[i] = vec4(0.0);
    const int c1 = min(c0 + kb, pc.cin4);
    for (int c4 = c0; c4 < c1; ++c4) {
      vec4 wv[4 * TC];
      for (int k = 0; k < 4; ++k) {
        for (int j = 0; j < TC; ++j) wv[k * TC + j] = IN1(wr + j);
        wr += pc.cout4p;
      }
      for (int i = 0; i < TP; ++i) {
        const vec4 v = IN0(src[i] + c4);
        for (int j = 0; j < TC; ++j) {
          s[i * TC + j] = fma(vec4(v.x), wv[j], fma(vec4(v.y), wv[TC + j],
                          fma(vec4(v.z), wv[2 * TC + j], fma(vec4(v.w), wv[3 * TC + j], s[i * TC + j]))));
        }
      }
    }
    for (int i = 0; i < TP * TC; ++i) a[i] += s[i];
  }
  for (int i = 0; i < TP; ++i) {
    const int p = p0 + i;
    if (p >= pc.pixels) break;
    const int dst = p * pc.out_stride4 + pc.out_offset4 + co;
    for (int j = 0; j < TC; ++j) {
      if (co + j < pc.cout4) y[dst + j] = activate(a[i * TC + j], co + j);
    }
  }
}
