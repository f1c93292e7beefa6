// Portable random numbers for the simulator. std::mt19937_64 is specified bit-exactly by the
// standard, but the std:: distributions are not (their output differs between library
// versions), so every transform here is written out: uniform doubles from the top 53 bits,
// polar-method normals, Knuth/normal-approximation Poisson. The same seed gives the same
// sequence on every conforming platform with an IEEE-754 libm.
#pragma once

#include <cstdint>
#include <random>

namespace mocap::sim {

// SplitMix64 finaliser: a well-mixed 64-bit hash, used to derive independent seeds
// (per frame, per view) from one master seed.
std::uint64_t mix_seed(std::uint64_t a, std::uint64_t b);

class Rng {
 public:
  explicit Rng(std::uint64_t seed = 1) : engine_(seed) {}

  void reseed(std::uint64_t seed) {
    engine_.seed(seed);
    has_spare_ = false;
  }

  std::uint64_t next_u64() { return engine_(); }
  // Uniform in [0, 1).
  double uniform() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
  // Uniform in [lo, hi).
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  // Uniform integer in [0, n); 0 when n <= 0.
  int uniform_int(int n);
  bool bernoulli(double p) { return uniform() < p; }
  // Standard normal N(0, 1) (Marsaglia polar method; the second value of each pair is cached).
  double normal();
  double normal(double mean, double sd) { return mean + sd * normal(); }
  // Poisson with the given mean (Knuth's product method up to mean 30, rounded normal
  // approximation above); 0 for mean <= 0.
  int poisson(double mean);
  // Number of failures before the first success of a Bernoulli(p) sequence (geometric);
  // a large value when p <= 0.
  int geometric(double p);
  // Same, with log(1 - p) precomputed by the caller (p in (0, 1), so the argument is < 0).
  int geometric_log(double log_one_minus_p);

 private:
  std::mt19937_64 engine_;
  double spare_ = 0.0;
  bool has_spare_ = false;
};

}  // namespace mocap::sim
