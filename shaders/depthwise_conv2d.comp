#version 450
// Depthwise KHxKW convolution (channel multiplier 1), any stride and SAME/VALID padding. One
// invocation = one output pixel x one vec4 channel group; adjacent invocations take adjacent
// groups of the same pixel so their loads are contiguous. Weights are [KH][KW][c4] vec4.
#extension GL_GOOGLE_include_directive : require
layout(local_size_x_id = 0) in;
#include "activation.glsl"
layout(constant_id = 2) const int KH = 3;
layout(constant_id = 3) const int KW = 3;

layout(std430, binding = 0) readonly buffer In { vec4 x[]; };
layout(std430, binding = 1) readonly buffer Weights { vec4 w[]; };
layout(std430, binding = 2) readonly buffer Bias { vec4 b[]; };
layout(std430, binding = 3) writeonly buffer Out { vec4 y[]; };

layout(push_constant) uniform Params {
  int n, in_h, in_w, c4, in_stride4;
  int out_h, out_w, out_stride4;
  int stride_h, stride_w, pad_top, pad_left;
} pc;

void main() {
  const int gid = int(gl_GlobalInvocationID.x);
  const int c = gid % pc.c4;
  int p = gid / pc.c4;
  const int ox = p % pc.out_w;
  p /= pc.out_w;
  const int oy = p % pc.out_h;
  const int bn = p / pc.out_h;
  if (bn >= pc.n) return;
  vec4 acc = b[c];
  for (int ky = 0; ky < KH; ++ky) {
    const int iy = oy * pc.stride_h - pc.pad_top + ky;
    if (iy < 0 || iy >= pc.in_h) continue;
    for (int kx = 0; kx < KW; ++kx) {
      const int ix = ox * pc.stride_w - pc.pad_left + kx;
      if (ix < 0 || ix >= pc.in_w) continue;
      acc = fma(x[((bn * pc.in_h + iy) * pc.in_w + ix) * pc.in_stride4 + c], w[(ky * KW + kx) * pc.c4 + c],
                acc);
    }
  }
  y[((bn * pc.out_h + oy) * pc.out_w + ox) * pc.out_stride4 + c] = activate(acc, c);
}
