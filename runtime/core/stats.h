// Order statistics of samples, one definition for the whole project: the median every report
// prints, percentiles (linear interpolation between closest ranks, as numpy's default) for
// error distributions, and the nearest-rank p99 of latency windows.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace mocap {

// The median (mean of the two middle values for an even count); 0 for no samples.
double median(std::vector<double> v);

// The middle sample (the upper of the two middle ones for an even count): a value that occurred,
// for integer clock readings and wherever the result must be one of the samples; T{} for none.
template <typename T>
T sample_median(std::vector<T> v) {
  if (v.empty()) return T{};
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// The q-quantile, q in [0, 1] (clamped), linearly interpolated between closest ranks; 0 for no
// samples.
double percentile(std::vector<double> v, double q);

// Latency of a stage over a window of samples (milliseconds).
struct LatencyStats {
  std::uint64_t count = 0;
  double median_ms = 0;
  double p99_ms = 0;  // nearest rank: a value that occurred
  double max_ms = 0;
};
LatencyStats latency_stats(std::vector<double> samples_ms);

}  // namespace mocap
