#version 450
// General KHxKW convolution, any stride, TensorFlow SAME/VALID padding given as pad_top/left.
// One invocation = one output pixel x one vec4 group of output channels. Weights are
// [KH][KW][cin4 * 4][cout4] vec4 (input channels zero-padded to a multiple of 4), bias [cout4].
// Used where a 1x1 GEMM or depthwise kernel does not apply (e.g. the network's first layer).
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
  int n, in_h, in_w, cin4, in_stride4;
  int out_h, out_w, cout4, out_stride4, out_offset4;
  int stride_h, stride_w, pad_top, pad_left;
} pc;

void main() {
  const int gid = int(gl_GlobalInvocationID.x);
  const int co = gid % pc.cout4;
  int p = gid / pc.cout4;
  const int ox = p % pc.out_w;
  p /= pc.out_w;
  const int oy = p % pc.out_h;
  const int bn = p / pc.out_h;
  if (bn >= pc.n) return;
  vec4 acc = b[co];
  for (int ky = 0; ky < KH; ++ky) {
    const int iy = oy * pc.stride_h - pc.pad_top + ky;
    if (iy < 0 || iy >= pc.in_h) continue;
    for (int kx = 0; kx < KW; ++kx) {
      const int ix = ox * pc.stride_w - pc.pad_left + kx;
      if (ix < 0 || ix >= pc.in_w) continue;
      const int src = ((bn * pc.in_h + iy) * pc.in_w + ix) * pc.in_stride4;
      int wr = ((ky * KW + kx) * pc.cin4 * 4) * pc.cout4 + co;
      for (int c4 = 0; c4 < pc.cin4; ++c4) {
        const vec4 v = x[src + c4];
        acc = fma(vec4(v.x), w[wr], acc);
        acc = fma(vec4(v.y), w[wr + pc.cout4], acc);
        acc = fma(vec4(v.z), w[wr + 2 * pc.cout4], acc);
        acc = fma(vec4(v.w), w[wr + 3 * pc.cout4], acc);
        wr += 4 * pc.cout4;
      }
    }
  }
  const int ob = ((bn * pc.out_h + oy) * pc.out_w + ox) * pc.out_stride4 + pc.out_offset4;
  y[ob + co] = activate(acc, co);
}
