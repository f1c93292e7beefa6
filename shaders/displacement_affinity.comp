#version 450
// PoseNet limb affinity (GPU version of nn::displacement_affinity_cpu, which documents the
// formula): for edge e, parent candidate i and child candidate j of view n,
//   a = (exp(-|p + fwd_e(p) - c|^2 / 2s^2) + exp(-|c + bwd_e(c) - p|^2 / 2s^2)) / 2.
// One invocation per (view, edge, i, j) over the KMAX x KMAX slots; slots beyond the
// candidate counts are written as 0. Candidates come from heatmap_peaks.comp.
#extension GL_GOOGLE_include_directive : require
layout(local_size_x_id = 0) in;
layout(constant_id = 1) const int KMAX = 16;
#include "tables.glsl"

layout(std430, binding = 0) readonly buffer Cand { vec4 cand[]; };      // [N,J,KMAX]
layout(std430, binding = 2) readonly buffer Fwd { float fwd[]; };       // [N,H,W,2E]
layout(std430, binding = 3) readonly buffer Bwd { float bwd[]; };       // [N,H,W,2E]
layout(std140, binding = 4) uniform Edges { ivec4 edges2[32]; };       // 2 x (parent, child)
layout(std430, binding = 5) writeonly buffer Aff { float aff[]; };      // [N,E,KMAX,KMAX]

layout(push_constant) uniform Params {
  int views;
  int cells;  // H * W
  int joints;
  int edges_count;
  float inv_2s2;
} pc;

void main() {
  const int gid = int(gl_GlobalInvocationID.x);
  const int per_edge = KMAX * KMAX;
  if (gid >= pc.views * pc.edges_count * per_edge) return;
  const int j = gid % KMAX;
  const int i = (gid / KMAX) % KMAX;
  const int e = (gid / per_edge) % pc.edges_count;
  const int n = gid / (per_edge * pc.edges_count);
  const ivec2 edge = (e & 1) == 0 ? edges2[e >> 1].xy : edges2[e >> 1].zw;
  const int pa = n * pc.joints + edge.x;
  const int ch = n * pc.joints + edge.y;
  if (i >= kept_candidates(pa) || j >= kept_candidates(ch)) {
    aff[gid] = 0.0;
    return;
  }
  const vec4 p = cand[pa * KMAX + i];
  const vec4 c = cand[ch * KMAX + j];
  const int E = pc.edges_count;
  const int fo = (n * pc.cells + int(p.w)) * 2 * E;
  const int bo = (n * pc.cells + int(c.w)) * 2 * E;
  const float fy = p.y + fwd[fo + e] - c.y;
  const float fx = p.x + fwd[fo + E + e] - c.x;
  const float by = c.y + bwd[bo + e] - p.y;
  const float bx = c.x + bwd[bo + E + e] - p.x;
  aff[gid] = 0.5 * (exp(-(fx * fx + fy * fy) * pc.inv_2s2) + exp(-(bx * bx + by * by) * pc.inv_2s2));
}
