#version 450
// KHxKW max pooling (kMaxPool), any stride, SAME/VALID padding; taps outside the input never
// win (TensorFlow semantics). One invocation per output pixel x vec4 channel group, adjacent
// invocations on adjacent groups of one pixel.
#extension GL_GOOGLE_include_directive : require
layout(local_size_x_id = 0) in;
#include "activation.glsl"
#include "inputs.glsl"
layout(constant_id = 2) const int KH = 2;
layout(constant_id = 3) const int KW = 2;

layout(std430, binding = 3) writeonly buffer Out { vec4 y[]; };

layout(push_constant) uniform Params {
  int n, in_h, in_w, c4;
  int out_h, out_w;
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
  const int y0 = oy * pc.stride_h - pc.pad_top;
  const int x0 = ox * pc.stride_w - pc.pad_left;
  vec4 m = vec4(-3.402823466e38);
  for (int ky = 0; ky < KH; ++ky) {
    const int iy = y0 + ky;
    if (iy < 0 || iy >= pc.in_h) continue;
    for (int kx = 0; kx < KW; ++kx) {
      const int ix = x0 + kx;
      if (ix < 0 || ix >= pc.in_w) continue;
      m = max(m, IN0(((bn * pc.in_h + iy) * pc.in_w + ix) * pc.c4 + c));
    }
  }
  y[((bn * pc.out_h + oy) * pc.out_w + ox) * pc.c4 + c] = activate(m, c);
}
