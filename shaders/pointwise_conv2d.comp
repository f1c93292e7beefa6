#version 450
// 1x1 convolution (a GEMM over pixels): y[p][co] = act(b[co] + sum_ci x[p][ci] w[ci][co]).
// Activations are NHWC with channels in vec4 groups (C4). Each invocation computes 8 pixels x
// 2 vec4 output groups (16 vec4 accumulators, no shared memory, no barriers: the register-
// blocked shape lavapipe runs fastest, see docs/gpu.md). Weights are [cin4 * 4][cout4p] vec4
// with cout4p = cout4 rounded up to even; bias is [cout4p].
#extension GL_GOOGLE_include_directive : require
layout(local_size_x_id = 0) in;
#include "activation.glsl"

layout(std430, binding = 0) readonly buffer In { vec4 x[]; };
layout(std430, binding = 1) readonly buffer Weights { vec4 w[]; };
layout(std430, binding = 2) readonly buffer Bias { vec4 b[]; };
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

const int TP = 8;

void main() {
  const int ncb = pc.cout4p / 2;
  const int gid = int(gl_GlobalInvocationID.x);
  const int cb = gid % ncb;
  const int p0 = (gid / ncb) * TP;
  if (p0 >= pc.pixels) return;
  const int co = cb * 2;
  vec4 a0[TP];
  vec4 a1[TP];
  int src[TP];
  for (int i = 0; i < TP; ++i) {
    a0[i] = b[co];
    a1[i] = b[co + 1];
    src[i] = min(p0 + i, pc.pixels - 1) * pc.in_stride4 + pc.in_offset4;
  }
  // Two-level accumulation: each block of KB input groups is summed on its own, then added to
  // the total, which keeps fp32 rounding error near that of a pairwise sum on 384+ channels.
  const int KB = 16;
  int wr = co;
  for (int c0 = 0; c0 < pc.cin4; c0 += KB) {
    vec4 s0[TP];
    vec4 s1[TP];
    for (int i = 0; i < TP; ++i) {
      s0[i] = vec4(0.0);
      s1[i] = vec4(0.0);
    }
    const int c1 = min(c0 + KB, pc.cin4);
    for (int c4 = c0; c4 < c1; ++c4) {
      const vec4 w00 = w[wr], w01 = w[wr + 1];
      wr += pc.cout4p;
      const vec4 w10 = w[wr], w11 = w[wr + 1];
      wr += pc.cout4p;
      const vec4 w20 = w[wr], w21 = w[wr + 1];
      wr += pc.cout4p;
      const vec4 w30 = w[wr], w31 = w[wr + 1];
      wr += pc.cout4p;
      for (int i = 0; i < TP; ++i) {
        const vec4 v = x[src[i] + c4];
        s0[i] = fma(vec4(v.x), w00, fma(vec4(v.y), w10, fma(vec4(v.z), w20, fma(vec4(v.w), w30, s0[i]))));
        s1[i] = fma(vec4(v.x), w01, fma(vec4(v.y), w11, fma(vec4(v.z), w21, fma(vec4(v.w), w31, s1[i]))));
      }
    }
    for (int i = 0; i < TP; ++i) {
      a0[i] += s0[i];
      a1[i] += s1[i];
    }
  }
  for (int i = 0; i < TP; ++i) {
    const int p = p0 + i;
    if (p >= pc.pixels) break;
    const int dst = p * pc.out_stride4 + pc.out_offset4 + co;
    y[dst] = activate(a0[i], co);
    if (co + 1 < pc.cout4) y[dst + 1] = activate(a1[i], co + 1);
  }
}
