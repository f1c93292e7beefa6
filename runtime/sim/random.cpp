#include "runtime/sim/random.h"

#include <cmath>
#include <limits>

namespace mocap::sim {

std::uint64_t mix_seed(std::uint64_t a, std::uint64_t b) {
  std::uint64_t z = a + 0x9E3779B97F4A7C15ULL * (b + 1);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

int Rng::uniform_int(int n) {
  if (n <= 0) return 0;
  const int k = static_cast<int>(uniform() * static_cast<double>(n));
  return k < n ? k : n - 1;
}

double Rng::normal() {
  if (has_spare_) {
    has_spare_ = false;
    return spare_;
  }
  // Marsaglia's polar method: two normals per accepted point, no trigonometry. Both
  // coordinates come from one 64-bit draw (32 bits each, ample for noise).
  double u = 0.0;
  double v = 0.0;
  double s = 0.0;
  do {
    const std::uint64_t bits = engine_();
    u = static_cast<double>(bits >> 32) * 0x1.0p-31 - 1.0;
    v = static_cast<double>(bits & 0xFFFFFFFFULL) * 0x1.0p-31 - 1.0;
    s = u * u + v * v;
  } while (s >= 1.0 || s == 0.0);
  const double f = std::sqrt(-2.0 * std::log(s) / s);
  spare_ = v * f;
  has_spare_ = true;
  return u * f;
}

int Rng::poisson(double mean) {
  if (!(mean > 0.0)) return 0;
  if (mean > 30.0) {
    const double x = std::round(normal(mean, std::sqrt(mean)));
    return x < 0.0 ? 0 : static_cast<int>(x);
  }
  const double limit = std::exp(-mean);
  int k = 0;
  double p = uniform();
  while (p > limit) {
    ++k;
    p *= uniform();
  }
  return k;
}

int Rng::geometric(double p) {
  constexpr int kNever = std::numeric_limits<int>::max() / 2;
  if (!(p > 0.0)) return kNever;
  if (p >= 1.0) return 0;
  return geometric_log(std::log1p(-p));
}

int Rng::geometric_log(double log_one_minus_p) {
  constexpr int kNever = std::numeric_limits<int>::max() / 2;
  if (!(log_one_minus_p < 0.0)) return kNever;
  const double u = 1.0 - uniform();  // (0, 1]
  const double k = std::floor(std::log(u) / log_one_minus_p);
  return k < static_cast<double>(kNever) ? static_cast<int>(k) : kNever;
}

}  // namespace mocap::sim
