#version 450
// OpenPose PAF line integral (GPU version of nn::paf_affinity_cpu, which documents the rule):
// for limb l (joints a -> b, field channels cx, cy), candidate i of a and j of b in view n,
// K points on the segment are read at the nearest PAF cell and dotted with the unit limb
// direction; score = clamp(mean, 0, 1) when the fraction of samples above min_dot reaches
// min_fraction, else 0. One invocation per (view, limb, i, j) over KMAX x KMAX slots; slots
// beyond the candidate counts are written as 0.
#extension GL_GOOGLE_include_directive : require
layout(local_size_x_id = 0) in;
layout(constant_id = 1) const int KMAX = 16;
#include "tables.glsl"

layout(std430, binding = 0) readonly buffer Cand { vec4 cand[]; };      // [N,J,KMAX]
layout(std430, binding = 2) readonly buffer Paf { float paf[]; };       // [N,H,W,C]
layout(std140, binding = 3) uniform Limbs { ivec4 limbs[64]; };        // (a, b, cx, cy)
layout(std430, binding = 4) writeonly buffer Score { float score[]; };  // [N,L,KMAX,KMAX]
layout(std430, binding = 5) writeonly buffer Frac { float frac[]; };    // [N,L,KMAX,KMAX]

layout(push_constant) uniform Params {
  int views;
  int h;
  int w;
  int channels;
  int joints;
  int limbs_count;
  int samples;
  float inv_stride;
  float min_dot;
  float min_fraction;
} pc;

void main() {
  const int gid = int(gl_GlobalInvocationID.x);
  const int per_limb = KMAX * KMAX;
  if (gid >= pc.views * pc.limbs_count * per_limb) return;
  const int j = gid % KMAX;
  const int i = (gid / KMAX) % KMAX;
  const int l = (gid / per_limb) % pc.limbs_count;
  const int n = gid / (per_limb * pc.limbs_count);
  const ivec4 limb = limbs[l];
  const int ja = n * pc.joints + limb.x;
  const int jb = n * pc.joints + limb.y;
  score[gid] = 0.0;
  frac[gid] = 0.0;
  if (i >= kept_candidates(ja) || j >= kept_candidates(jb)) return;
  const vec2 a = cand[ja * KMAX + i].xy;
  const vec2 b = cand[jb * KMAX + j].xy;
  const vec2 v = b - a;
  const float len = sqrt(v.x * v.x + v.y * v.y);
  if (!(len >= 1e-3)) return;
  const vec2 u = v / len;
  float sum = 0.0;
  int above = 0;
  for (int k = 0; k < pc.samples; ++k) {
    const float t = float(k) / float(pc.samples - 1);
    const float px = (a.x + t * v.x) * pc.inv_stride;
    const float py = (a.y + t * v.y) * pc.inv_stride;
    const int cx = clamp(int(floor(px + 0.5)), 0, pc.w - 1);
    const int cy = clamp(int(floor(py + 0.5)), 0, pc.h - 1);
    const int o = ((n * pc.h + cy) * pc.w + cx) * pc.channels;
    const float d = paf[o + limb.z] * u.x + paf[o + limb.w] * u.y;
    sum += d;
    if (d > pc.min_dot) ++above;
  }
  const float fraction = float(above) / float(pc.samples);
  frac[gid] = fraction;
  score[gid] = fraction >= pc.min_fraction ? clamp(sum / float(pc.samples), 0.0, 1.0) : 0.0;
}
