#version 450
// Depthwise KHxKW convolution (channel multiplier 1), any stride and SAME/VALID padding. One
// invocation = TX consecutive output pixels of one row x one vec4 channel group: the input row
// segment under the TX windows is fetched once per kernel row and reused by every window and
// tap (register blocking; lavapipe is bound by fetches, see docs/gpu.md). Out-of-image taps
// read a clamped texel multiplied by zero, so there is no divergent branch. Adjacent
// invocations take adjacent channel groups of the same pixels. Weights are [KH][KW][c4] vec4.
#extension GL_GOOGLE_include_directive : require
layout(local_size_x_id = 0) in;
#include "activation.glsl"
#include "inputs.glsl"
layout(constant_id = 2) const int KH = 3;
layout(constant_id = 3) const int KW = 3;
layout(constant_id = 4) const int SW = 1;  // horizontal stride
layout(constant_id = 5) const int TX = 4;  // output pixels per invocation
const int NCOL = (TX - 1) * SW + KW;       // input columns under the TX windows

layout(std430, binding = 3) writeonly buffer Out { vec4 y[]; };

layout(push_constant) uniform Params {
  int n, in_h, in_w, c4, in_stride4;
  int out_h, out_w, out_stride4;
  int stride_h, stride_w, pad_top, pad_left;
  int x_blocks;  // ceil(out_w / TX)
} pc;

void main() {
  const int gid = int(gl_GlobalInvocationID.x);
  const int c = gid % pc.c4;
  int p = gid / pc.c4;
  const int ox0 = (p % pc.x_blocks) * TX;
  p /= pc.x_blocks;
  const int oy = p % pc.out_h;
  const int bn = p / pc.out_h;
  if (bn >= pc.n) return;
  vec4 acc[TX];
  for (int t = 0; t < TX; ++t) acc[t] = consts[c];
  const int ix0 = ox0 * SW - pc.pad_left;
  for (int ky = 0; ky < KH; ++ky) {
    const int iy = oy * pc.stride_h - pc.pad_top + ky;
    const float row_ok = float(iy >= 0 && iy < pc.in_h);
    const int row = (bn * pc.in_h + clamp(iy, 0, pc.in_h - 1)) * pc.in_w;
    vec4 v[NCOL];
    for (int i = 0; i < NCOL; ++i) {
      const int ix = ix0 + i;
      const float ok = row_ok * float(ix >= 0 && ix < pc.in_w);
      v[i] = IN0((row + clamp(ix, 0, pc.in_w - 1)) * pc.in_stride4 + c) * ok;
    }
    for (int kx = 0; kx < KW; ++kx) {
      const vec4 wv = IN1((ky * KW + kx) * pc.c4 + c);
      for (int t = 0; t < TX; ++t) acc[t] = fma(v[t * SW + kx], wv, acc[t]);
    }
  }
  for (int t = 0; t < TX; ++t) {
    const int ox = ox0 + t;
    if (ox >= pc.out_w) break;
    y[((bn * pc.out_h + oy) * pc.out_w + ox) * pc.out_stride4 + c] = activate(acc[t], c);
  }
}
