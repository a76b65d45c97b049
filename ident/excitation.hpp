// Excitation programs for identification and recording them on the simulated gantry axis.
//
// - random_moves: the thesis's Appendix D.3 input, "a series of small, random, instantaneous
//   moves designed to stay well within the maximum velocity limits of the motor", here on top of
//   a slow back-and-forth drift across `travel_mm` so position-dependent effects are visible.
// - sine_sweep: a logarithmic chirp (the delta paper measures FRFs with sine excitation).
// - record_gantry_trace: runs a commanded-position program on sim::GantryAxis through the ideal
//   sim::StepDriver and samples commanded steps and encoder at the program's rate (trace CSV v1).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/result.hpp"
#include "ident/trace.hpp"
#include "sim/gantry_params.hpp"

namespace feedloop::ident {

struct RandomMovesOptions {
  double duration_s = 30.0;
  double sample_rate_hz = 1000.0;
  double step_min_mm = 0.01;     // size of one instantaneous move (random sign)
  double step_max_mm = 0.08;
  double dwell_min_s = 0.03;     // hold time after each move
  double dwell_max_s = 0.15;
  double travel_mm = 80.0;       // the drift goes 0 -> travel -> 0 once over the duration (0: none)
  uint64_t seed = 1;
};

struct SineSweepOptions {
  double duration_s = 20.0;
  double sample_rate_hz = 1000.0;
  double f_start_hz = 2.0;
  double f_end_hz = 120.0;
  double amplitude_mm = 0.05;
};

// Commanded positions (mm), one per sample, starting at 0.
std::vector<double> random_moves(const RandomMovesOptions& o);
std::vector<double> sine_sweep(const SineSweepOptions& o);

// Runs the program on a GantryAxis built from `params` (steps at params' mm per step) and returns a
// one-axis trace named `axis_name`: time_s = k / rate, cmd = steps sent x mm per step, meas =
// encoder counts x mm per count (both relative to power-on). Metadata: sample_rate_hz, source=sim.
// Errors: invalid parameters, a rate <= 0, an empty program.
Result<Trace> record_gantry_trace(const sim::GantryAxisParams& params, const std::vector<double>& cmd_mm,
                                  double sample_rate_hz, const std::string& axis_name);

}  // namespace feedloop::ident
