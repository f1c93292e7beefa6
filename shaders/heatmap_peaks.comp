#version 450
// Heatmap peaks -> joint candidates (GPU version of nn::find_peaks_cpu, which documents the
// rules): a cell is a peak when its logit is >= the threshold logit and greater than its 8
// neighbours' (an equal neighbour with a smaller cell index wins); the KMAX best peaks of each
// (view, joint) are kept, best first (ties by cell index), refined by the offset field, and
// the others counted. One invocation per (view, joint): the heatmap is small (PoseNet at 353:
// 23x23x17) and one sequential scan keeps the selection exact and deterministic.
layout(local_size_x_id = 0) in;
layout(constant_id = 1) const int KMAX = 16;  // candidates kept per (view, joint)

layout(std430, binding = 0) readonly buffer Heat { float heat[]; };       // [N,H,W,J] logits
layout(std430, binding = 1) readonly buffer Offsets { float offs[]; };    // [N,H,W,2J]
layout(std430, binding = 2) writeonly buffer Cand { vec4 cand[]; };       // [N,J,KMAX]
layout(std430, binding = 3) writeonly buffer Counts { int counts[]; };    // [N,J,2]

layout(push_constant) uniform Params {
  int views;
  int h;
  int w;
  int joints;
  float threshold_logit;
  float stride_px;
} pc;

void main() {
  const int gid = int(gl_GlobalInvocationID.x);
  if (gid >= pc.views * pc.joints) return;
  const int n = gid / pc.joints;
  const int k = gid % pc.joints;
  const int J = pc.joints;
  const int base = n * pc.h * pc.w;
  float best_logit[KMAX];
  int best_cell[KMAX];
  int kept = 0;
  int total = 0;
  for (int y = 0; y < pc.h; ++y) {
    for (int x = 0; x < pc.w; ++x) {
      const int cell = y * pc.w + x;
      const float v = heat[(base + cell) * J + k];
      if (!(v >= pc.threshold_logit)) continue;
      bool peak = true;
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const int yy = y + dy;
          const int xx = x + dx;
          if ((dy == 0 && dx == 0) || yy < 0 || xx < 0 || yy >= pc.h || xx >= pc.w) continue;
          const int nc = yy * pc.w + xx;
          const float nb = heat[(base + nc) * J + k];
          if (nb > v || (nb == v && nc < cell)) peak = false;
        }
      }
      if (!peak) continue;
      ++total;
      // Insert after every kept entry with a logit >= v (stable: earlier cells first).
      int pos = kept;
      while (pos > 0 && best_logit[pos - 1] < v) --pos;
      if (pos >= KMAX) continue;
      const int last = min(kept, KMAX - 1);
      for (int i = last; i > pos; --i) {
        best_logit[i] = best_logit[i - 1];
        best_cell[i] = best_cell[i - 1];
      }
      best_logit[pos] = v;
      best_cell[pos] = cell;
      kept = min(kept + 1, KMAX);
    }
  }
  const int dst = (n * J + k) * KMAX;
  for (int i = 0; i < kept; ++i) {
    const int cell = best_cell[i];
    const int cy = cell / pc.w;
    const int cx = cell % pc.w;
    const int o = (base + cell) * 2 * J;
    const float score = 1.0 / (1.0 + exp(-best_logit[i]));
    cand[dst + i] = vec4(float(cx) * pc.stride_px + offs[o + J + k],
                         float(cy) * pc.stride_px + offs[o + k], score, float(cell));
  }
  counts[(n * J + k) * 2] = kept;
  counts[(n * J + k) * 2 + 1] = total - kept;
}
