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

// Every latency since the start in fixed buckets (a Prometheus histogram: monitoring computes
// quantiles over any period from the counters). counts[i] = samples <= kBoundsMs[i] and above
// the bound before; counts[kBuckets] = samples above the last bound.
struct LatencyHistogram {
  static constexpr int kBuckets = 14;
  static constexpr double kBoundsMs[kBuckets] = {0.25, 0.5, 1,   2,   5,   10,   20,
                                                 35,   50,  100, 200, 500, 1000, 5000};
  std::uint64_t counts[kBuckets + 1] = {};
  std::uint64_t count = 0;
  double sum_ms = 0;
  void add(double ms) {
    int i = 0;
    while (i < kBuckets && ms > kBoundsMs[i]) ++i;
    ++counts[i];
    ++count;
    sum_ms += ms;
  }
  // Samples <= kBoundsMs[i] (Prometheus "le" buckets are cumulative).
  std::uint64_t cumulative(int i) const {
    std::uint64_t n = 0;
    for (int k = 0; k <= i && k <= kBuckets; ++k) n += counts[k];
    return n;
  }
};

}  // namespace mocap
