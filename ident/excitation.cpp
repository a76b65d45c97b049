// Excitation programs (see excitation.hpp).
#include "ident/excitation.hpp"

#include <cmath>

#include "core/rng.hpp"

namespace feedloop::ident {
namespace {
constexpr double kPi = 3.14159265358979323846;
}

std::vector<double> random_moves(const RandomMovesOptions& o) {
  const auto n = static_cast<size_t>(std::max(0.0, std::round(o.duration_s * o.sample_rate_hz)));
  std::vector<double> u(n, 0.0);
  Rng rng(o.seed);
  double offset_mm = 0.0;  // sum of the random moves
  double next_move_s = 0.0;
  for (size_t k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) / o.sample_rate_hz;
    if (t >= next_move_s && k > 0) {
      const double size = o.step_min_mm + (o.step_max_mm - o.step_min_mm) * rng.uniform();
      // Random sign, biased back towards zero so the moves stay around the drift.
      const double p_up = offset_mm > 0.0 ? 0.35 : 0.65;
      offset_mm += rng.uniform() < p_up ? size : -size;
      next_move_s = t + o.dwell_min_s + (o.dwell_max_s - o.dwell_min_s) * rng.uniform();
    }
    // Triangle drift 0 -> travel -> 0.
    const double phase = o.duration_s > 0.0 ? t / o.duration_s : 0.0;
    const double drift = o.travel_mm * (phase < 0.5 ? 2.0 * phase : 2.0 * (1.0 - phase));
    u[k] = drift + offset_mm;
  }
  return u;
}

std::vector<double> sine_sweep(const SineSweepOptions& o) {
  const auto n = static_cast<size_t>(std::max(0.0, std::round(o.duration_s * o.sample_rate_hz)));
  std::vector<double> u(n, 0.0);
  const double ratio = o.f_end_hz / o.f_start_hz;
  const double k_rate = std::log(ratio) / o.duration_s;
  for (size_t k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) / o.sample_rate_hz;
    // Exponential chirp: phase = 2 pi f0 (e^{kt} - 1) / k.
    const double phase = 2.0 * kPi * o.f_start_hz * (std::exp(k_rate * t) - 1.0) / k_rate;
    u[k] = o.amplitude_mm * std::sin(phase);
  }
  return u;
}
}  // namespace feedloop::ident
