// Small read-only tables of the post-processing kernels as uniform buffers (an include, not a
// kernel), so that no kernel binds more than four storage buffers (the Vulkan spec's minimum
// maxPerStageDescriptorStorageBuffers). std140 gives array elements a 16-byte stride, so the
// tables are ivec4 arrays; their sizes are what runtime/gpu/pose_kernels.cpp allocates and
// checks (kMaxCandidateCounts, kMaxLimbs, kMaxEdges there).
//
// The candidate counts heatmap_peaks.comp writes ([N,J,2] ints: kept, dropped): 16 KiB, the
// spec's minimum maxUniformBufferRange.
layout(std140, binding = 1) uniform Counts { ivec4 counts4[1024]; };
int kept_candidates(int view_joint) {
  const int k = view_joint * 2;
  return counts4[k >> 2][k & 3];
}
