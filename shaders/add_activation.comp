#version 450
// Elementwise y = act(a + b) (kAdd, two inputs of one shape), or y = act(a) (kActivation, when
// HAS_B is 0): one invocation per vec4 group, inputs read as every network kernel reads
// them (inputs.glsl). Padding lanes stay whatever the inputs hold there (zero or an activation of zero);
// nothing reads them.
#extension GL_GOOGLE_include_directive : require
layout(local_size_x_id = 0) in;
#include "activation.glsl"
#include "inputs.glsl"
layout(constant_id = 2) const int HAS_B = 1;

layout(std430, binding = 3) writeonly buffer Out { vec4 y[]; };

layout(push_constant) uniform Params {
  int groups;  // n * h * w * c4
  int c4;      // vec4 groups per pixel
} pc;

void main() {
  const int i = int(gl_GlobalInvocationID.x);
  if (i >= pc.groups) return;
  vec4 v = IN0(i);
  if (HAS_B != 0) v += IN1(i);
  y[i] = activate(v, i % pc.c4);
}
