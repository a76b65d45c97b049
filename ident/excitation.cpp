// Excitation programs and their recording on the simulator (see excitation.hpp).
#include "ident/excitation.hpp"

#include <cmath>

#include "sim/gantry_axis.hpp"
#include "sim/rng.hpp"
#include "sim/step_driver.hpp"

namespace feedloop::ident {
namespace {
constexpr double kPi = 3.14159265358979323846;
}

std::vector<double> random_moves(const RandomMovesOptions& o) {
  const auto n = static_cast<size_t>(std::max(0.0, std::round(o.duration_s * o.sample_rate_hz)));
  std::vector<double> u(n, 0.0);
  sim::Rng rng(o.seed);
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

Result<Trace> record_gantry_trace(const sim::GantryAxisParams& params, const std::vector<double>& cmd_mm,
                                  double sample_rate_hz, const std::string& axis_name) {
  if (!(sample_rate_hz > 0.0)) return Error{"sample rate must be > 0", {}};
  if (cmd_mm.empty()) return Error{"empty excitation program", {}};
  auto axis = sim::GantryAxis::create(params);
  if (!axis) return axis.error();
  sim::GantryAxis& plant = axis.value();
  const double start_mm = params.initial_pos_mm;
  sim::StepDriver driver(plant, plant.mm_per_step(), start_mm, 0.0);
  Trace trace;
  trace.metadata.emplace_back("sample_rate_hz", std::to_string(static_cast<long>(std::lround(sample_rate_hz))));
  trace.metadata.emplace_back("source", "sim");
  AxisTrace a{axis_name, {}, {}};
  a.cmd_mm.reserve(cmd_mm.size());
  a.meas_mm.reserve(cmd_mm.size());
  trace.time_s.reserve(cmd_mm.size());
  for (size_t k = 0; k < cmd_mm.size(); ++k) {
    const double t = static_cast<double>(k) / sample_rate_hz;
    if (k > 0) driver.update(t, start_mm + cmd_mm[k]);
    plant.advance_to(t);
    trace.time_s.push_back(t);
    a.cmd_mm.push_back(driver.commanded_mm() - start_mm);
    a.meas_mm.push_back(static_cast<double>(plant.read_encoder_counts(t)) * plant.encoder_mm_per_count());
  }
  trace.axes.push_back(std::move(a));
  return trace;
}

}  // namespace feedloop::ident
