#version 450
// General KHxKW convolution, any stride, TensorFlow SAME/VALID padding given as pad_top/left.
// One invocation = TX consecutive output pixels of a row x TC vec4 groups of output channels
// (register blocking: each input texel and weight texel fetched is used TC x 4 resp. TX
// times). Out-of-image taps read a clamped texel multiplied by zero (no divergent branch).
// Weights are [KH][KW][cin4 * 4][cout4p] vec4 (input channels zero-padded to a multiple of 4,
// output groups to a multiple of TC); the bias is the first cout4p constants (binding 2). Used
// where a 1x1 GEMM or depthwise kernel does not apply (e.g. the network's first layer).
#extension GL_GOOGLE_include_directive : require
layout(local_size_x_id = 0) in;
#include "activation.glsl"
#include "inputs.glsl"
layout(constant_id = 2) const int KH = 3;
layout(constant_id = 3) const int KW = 3;
layout(constant_id = 4) const int SW = 1;  // horizontal stride
layout(constant_id = 5) const int TX = 4;  // output pixels per invocation
layout(constant_id = 6) const int TC = 1;  // output vec4 groups per invocation
const int NCOL = (TX - 1) * SW + KW;       // input columns under the TX windows

layout(std430, binding = 3) writeonly buffer Out { vec4 y[]; };

layout(push_constant) uniform Params {
  int n, in_h, in_w, cin4, in_stride4;
  int out_h, out_w, cout4, out_stride4, out_offset4;
  int stride_h, stride_w, pad_top, pad_left;
  int x_blocks;  // ceil(out_w / TX)
  int cout4p;    // weight row length (vec4), a multiple of TC
} pc;

void main() {
  const int gid = int(gl_GlobalInvocationID.x);
  const int ncb = pc.cout4p / TC;
  const int co = (gid % ncb) * TC;
  int p = gid / ncb;
  const int ox0 = (p % pc.x_blocks) * TX;
  p /= pc.x_blocks;
  const int oy = p % pc.out_h;
  const int bn = p / pc.out_h;
  if (bn >= pc.n) return;
  vec4 acc[TX * TC];
  for (int t = 0; t < TX; ++t) {
    for (int j = 0; j < TC; ++j) acc[t * TC + j] = consts[co + j];
  }
  const int ix0 = ox0 * SW - pc.pad_left;
  for (int ky = 0; ky < KH; ++ky) {
    const int iy = oy * pc.stride_h - pc.pad_top + ky;
    const float row_ok = float(iy >= 0 && iy < pc.in_h);
    const int row = (bn * pc.in_h + clamp(iy, 0, pc.in_h - 1)) * pc.in_w;
    for (int c4 = 0; c4 < pc.cin4; ++c4) {
      vec4 v[NCOL];
      for (int i = 0; i < NCOL; ++i) {
        const int ix = ix0 + i;
        const float ok = row_ok * float(ix >= 0 && ix < pc.in_w);
        v[i] = IN0((row + clamp(ix, 0, pc.in_w - 1)) * pc.in_stride4 + c4) * ok;
      }
      for (int kx = 0; kx < KW; ++kx) {
        const int wr = ((ky * KW + kx) * pc.cin4 + c4) * 4 * pc.cout4p + co;
        for (int j = 0; j < TC; ++j) {
          const vec4 w0 = IN1(wr + j);
          const vec4 w1 = IN1(wr + pc.cout4p + j);
          const vec4 w2 = IN1(wr + 2 * pc.cout4p + j);
          const vec4 w3 = IN1(wr + 3 * pc.cout4p + j);
          for (int t = 0; t < TX; ++t) {
            const vec4 s = v[t * SW + kx];
            acc[t * TC + j] = fma(vec4(s.x), w0, fma(vec4(s.y), w1, fma(vec4(s.z), w2,
                              fma(vec4(s.w), w3, acc[t * TC + j]))));
          }
        }
      }
    }
  }
  const int ob = ((bn * pc.out_h + oy) * pc.out_w + ox0) * pc.out_stride4 + pc.out_offset4 + co;
  for (int t = 0; t < TX; ++t) {
    if (ox0 + t >= pc.out_w) break;
    for (int j = 0; j < TC; ++j) {
      if (co + j < pc.cout4) y[ob + t * pc.out_stride4 + j] = activate(acc[t * TC + j], co + j);
    }
  }
}
