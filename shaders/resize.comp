#version 450
// Integer-factor upsampling (kResizeNearest, kResizeBilinear): nearest takes input pixel
// (oy / f, ox / f); bilinear uses half-pixel centres, source (d + 0.5) / f - 0.5 clamped to
// the edge, as the CPU reference. One invocation per output pixel x vec4 channel group.
#extension GL_GOOGLE_include_directive : require
layout(local_size_x_id = 0) in;
#include "activation.glsl"
#include "inputs.glsl"
layout(constant_id = 2) const int BILINEAR = 1;

layout(std430, binding = 3) writeonly buffer Out { vec4 y[]; };

layout(push_constant) uniform Params {
  int n, in_h, in_w, c4;
  int out_h, out_w;
  int factor;
} pc;

vec4 at(int bn, int iy, int ix, int c) {
  return IN0(((bn * pc.in_h + iy) * pc.in_w + ix) * pc.c4 + c);
}

void main() {
  const int gid = int(gl_GlobalInvocationID.x);
  const int c = gid % pc.c4;
  int p = gid / pc.c4;
  const int ox = p % pc.out_w;
  p /= pc.out_w;
  const int oy = p % pc.out_h;
  const int bn = p / pc.out_h;
  if (bn >= pc.n) return;
  vec4 v;
  if (BILINEAR == 0) {
    v = at(bn, oy / pc.factor, ox / pc.factor, c);
  } else {
    const float f = float(pc.factor);
    const float sy = max(0.0, (float(oy) + 0.5) / f - 0.5);
    const float sx = max(0.0, (float(ox) + 0.5) / f - 0.5);
    const int y0 = min(int(sy), pc.in_h - 1);
    const int x0 = min(int(sx), pc.in_w - 1);
    const int y1 = min(y0 + 1, pc.in_h - 1);
    const int x1 = min(x0 + 1, pc.in_w - 1);
    const float fy = sy - float(y0);
    const float fx = sx - float(x0);
    const vec4 top = at(bn, y0, x0, c) * (1.0 - fx) + at(bn, y0, x1, c) * fx;
    const vec4 bot = at(bn, y1, x0, c) * (1.0 - fx) + at(bn, y1, x1, c) * fx;
    v = top * (1.0 - fy) + bot * fy;
  }
  y[((bn * pc.out_h + oy) * pc.out_w + ox) * pc.c4 + c] = activate(v, c);
}
