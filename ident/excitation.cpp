// Excitation programs (see excitation.hpp).
#include "ident/excitation.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

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

std::vector<double> calibration_program(const CalibrationProgramOptions& o) {
  std::vector<double> u;
  const double dt = 1.0 / o.sample_rate_hz;
  auto append_from = [&](const std::vector<double>& section) {
    const double base = u.empty() ? 0.0 : u.back();
    for (double x : section) u.push_back(base + x);
  };
  // A triangle back and forth of `span` at `speed` for `periods` periods (starts and ends at 0).
  auto triangle = [&](double span, double speed, double periods) {
    std::vector<double> s;
    if (span <= 0.0 || speed <= 0.0) return s;
    const double period_s = 2.0 * span / speed;
    const auto n = static_cast<size_t>(std::round(periods * period_s / dt));
    for (size_t k = 1; k <= n; ++k) {
      const double ph = std::fmod(static_cast<double>(k) * dt / period_s, 1.0);
      s.push_back(span * (ph < 0.5 ? 2.0 * ph : 2.0 * (1.0 - ph)));
    }
    return s;
  };
  // Each sample's section (mark() after a section is appended).
  enum Section : uint8_t { kRandomOrSweep, kReversals, kRuns };
  std::vector<uint8_t> section;
  auto mark = [&](Section s) { section.resize(u.size(), s); };
  for (int c = 0; c < o.cycles; ++c) {
    RandomMovesOptions ro;
    ro.duration_s = o.random_s;
    ro.sample_rate_hz = o.sample_rate_hz;
    ro.travel_mm = 0.0;  // the program's own drift is added at the end
    ro.seed = o.seed * 7919 + static_cast<uint64_t>(c);
    std::vector<double> rm = random_moves(ro);
    // random_moves ends away from its start by its last moves: ramp that offset out over the
    // section's last 0.2 s so the next section starts from the drift's end.
    if (!rm.empty()) {
      const double end_offset = rm.back();
      const size_t ramp = std::min(rm.size(), static_cast<size_t>(0.2 * o.sample_rate_hz));
      for (size_t i = 0; i < ramp; ++i)
        rm[rm.size() - ramp + i] -=
            end_offset * static_cast<double>(i + 1) / static_cast<double>(ramp);
    }
    append_from(rm);
    SineSweepOptions so;
    so.duration_s = o.sweep_s;
    so.sample_rate_hz = o.sample_rate_hz;
    so.f_start_hz = o.sweep_f_start_hz;
    so.f_end_hz = o.sweep_f_end_hz;
    so.amplitude_mm = o.sweep_amplitude_mm;
    std::vector<double> sw = sine_sweep(so);
    // Fade in and out over 0.1 s (the sweep starts with a velocity step otherwise).
    const size_t fade = std::min(sw.size() / 2, static_cast<size_t>(0.1 * o.sample_rate_hz));
    for (size_t i = 0; i < fade; ++i) {
      const double w = static_cast<double>(i) / static_cast<double>(fade);
      sw[i] *= w;
      sw[sw.size() - 1 - i] *= w;
    }
    append_from(sw);
    mark(kRandomOrSweep);
    for (double speed : o.reversal_speeds_mm_s)
      append_from(triangle(o.reversal_span_mm, speed, o.reversals_per_speed));
    mark(kReversals);
    append_from(triangle(o.run_mm, o.run_speed_mm_s, 1.0));
    mark(kRuns);
  }
  if (o.drift_speed_random_mm_s > 0.0 && o.drift_speed_others_mm_s > 0.0 && o.travel_mm > 0.0) {
    const double speed_mm_s[3] = {
        o.drift_speed_random_mm_s, o.drift_speed_others_mm_s,
        o.drift_speed_runs_mm_s < 0.0 ? o.drift_speed_others_mm_s : o.drift_speed_runs_mm_s};
    double x = 0.0, dir = 1.0;
    for (size_t k = 0; k < u.size(); ++k) {
      u[k] += x;
      x += dir * speed_mm_s[section[k]] * dt;
      if (x > o.travel_mm) x = 2.0 * o.travel_mm - x, dir = -1.0;
      if (x < 0.0) x = -x, dir = 1.0;
    }
    return u;
  }
  // One drift speed: the drift moves under every section (drift_through_all) or under the
  // random moves and the sweep only.
  auto drifts = [&](size_t k) -> size_t {
    return o.drift_through_all || section[k] == kRandomOrSweep ? 1 : 0;
  };
  size_t drift_samples = 0;
  for (size_t k = 0; k < u.size(); ++k) drift_samples += drifts(k);
  const double passes = static_cast<double>(std::max(o.drift_passes, 1));
  size_t moved = 0;
  for (size_t k = 0; k < u.size(); ++k) {
    const double phase = std::fmod(passes * static_cast<double>(moved) /
                                       static_cast<double>(std::max<size_t>(drift_samples, 1)),
                                   1.0);
    u[k] += o.travel_mm * (phase < 0.5 ? 2.0 * phase : 2.0 * (1.0 - phase));
    moved += drifts(k);
  }
  return u;
}

}  // namespace feedloop::ident
