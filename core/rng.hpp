// Seeded random numbers (the plant simulator's noise, identification's excitation programs):
// SplitMix64 plus a Box-Muller Gaussian. Written out here (instead of std::normal_distribution,
// whose output is implementation-defined) so that a given seed gives the same numbers on every
// standard library: simulations and excitations are reproducible bit for bit across machines.
#pragma once

#include <cmath>    // sqrt, log, cos, sin
#include <cstdint>  // uint64_t

namespace feedloop {

class Rng {
 public:
  explicit Rng(uint64_t seed) : state_(seed) {}

  // SplitMix64 (Steele, Lea, Flood 2014): a full-period 64-bit generator.
  uint64_t next_u64() {
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
  }

  // Uniform in (0, 1): never exactly 0, so log() below is finite.
  double uniform() { return (static_cast<double>(next_u64() >> 11) + 0.5) * (1.0 / 9007199254740992.0); }

  // Standard normal deviate (Box-Muller; the second value of each pair is kept for the next call).
  double gaussian() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    const double u1 = uniform();
    const double u2 = uniform();
    const double r = std::sqrt(-2.0 * std::log(u1));
    const double a = 6.283185307179586 * u2;
    spare_ = r * std::sin(a);
    has_spare_ = true;
    return r * std::cos(a);
  }

 private:
  uint64_t state_;
  double spare_ = 0.0;
  bool has_spare_ = false;
};

}  // namespace feedloop
