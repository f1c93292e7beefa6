#version 450
// One input of a channel concatenation (kConcat): copies its `in_c` channels into the output
// at channel `offset_c`, activation applied. Dispatched once per input with a barrier between,
// so inputs whose channel count is not a multiple of 4 land in shared vec4 groups without a
// race: the output is written per scalar lane. One invocation per input pixel x vec4 group.
#extension GL_GOOGLE_include_directive : require
layout(local_size_x_id = 0) in;
#include "activation.glsl"
#include "inputs.glsl"

layout(std430, binding = 3) writeonly buffer Out { float y[]; };

layout(push_constant) uniform Params {
  int pixels;       // n * h * w
  int in_c;         // channels of this input
  int in_c4;        // its vec4 groups per pixel
  int out_stride4;  // output vec4 groups per pixel
  int offset_c;     // first output channel
} pc;

void main() {
  const int gid = int(gl_GlobalInvocationID.x);
  const int g = gid % pc.in_c4;
  const int p = gid / pc.in_c4;
  if (p >= pc.pixels) return;
  const vec4 v = IN0(p * pc.in_c4 + g);
  for (int lane = 0; lane < 4; ++lane) {
    const int ch = g * 4 + lane;
    if (ch >= pc.in_c) break;
    const int oc = pc.offset_c + ch;
    y[p * pc.out_stride4 * 4 + oc] = activate(vec4(v[lane]), oc / 4)[oc % 4];
  }
}
