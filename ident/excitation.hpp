// Excitation programs for identification.
//
// - random_moves: the thesis's Appendix D.3 input, "a series of small, random, instantaneous
//   moves designed to stay well within the maximum velocity limits of the motor", here on top of
//   a slow back-and-forth drift across `travel_mm` so position-dependent effects are visible.
// - sine_sweep: a logarithmic chirp (the delta paper measures FRFs with sine excitation).
//
// A program is run on a machine by whoever owns the machine: on the simulated gantry axis by
// sim::record_gantry_trace (sim/experiments/gantry_recording.hpp), which ident does not depend on.
#pragma once

#include <cstdint>
#include <vector>

#include "core/result.hpp"

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

}  // namespace feedloop::ident
