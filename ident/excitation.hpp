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

// The calibration program: an excitation that separates the candidate effects (issue 15), as
// `cycles` repeats of one cycle, so that the training part of a fit and its held-out last 30 %
// both see every section, and the first cycle fits the screening window (FitOptions):
//   1. random small moves (thesis App. D.3): the baseline;
//   2. an exponential sine sweep f_start -> f_end at constant amplitude: resonances (modes);
//   3. triangle reversals of reversal_span_mm at each of reversal_speeds_mm_s: Coulomb friction
//      (a lag of about 2 F_c / k after every reversal, rounded by the bristles) against backlash
//      (a dead band of fixed width whatever the speed), and both directions of pull;
//   4. constant-speed runs of run_mm, forward and back: periodic position errors and
//      direction-dependent effects at steady speed.
// Under all of it a drift 0 -> travel_mm -> 0, drift_passes times over the whole program (2.9
// mm/s with the defaults), carries the sections across the travel: a periodic error is only
// claimed over at least two periods, so travel_mm bounds the longest period found (40 mm at 80
// mm). Sections are joined continuously (each starts where the last ended).
// The drift and the slowest reversals are below a bearing's Stribeck speed (a few mm/s), where a
// carriage whose friction falls from breakaway to sliding sticks and slips: a limit cycle whose
// phase no fitted model follows. Four passes and reversals at 6, 15 and 36 mm/s stay above it
// (friction's force right in every draw of the second simulator) but lose a microstep error and
// a direction ratio that the slow drift finds (docs/ident.md, "Faster than the Stribeck speed").
struct CalibrationProgramOptions {
  double sample_rate_hz = 1000.0;
  int cycles = 3;
  double random_s = 6.0;
  double sweep_s = 6.0;
  double sweep_f_start_hz = 5.0;
  // The FRF grid's top at 1 kHz (ident/fit.cpp). At 150 Hz, the former end, the sweep's fade-out
  // (its last 0.1 s: 142-150 Hz) left modes of 120-150 Hz half excited: the second simulator's
  // resonances of 123-146 Hz went unnamed (docs/ident.md, "The sweep to 200 Hz").
  double sweep_f_end_hz = 200.0;
  double sweep_amplitude_mm = 0.03;
  double reversal_span_mm = 1.0;
  double reversal_speeds_mm_s[3] = {2.0, 5.0, 12.0};
  double reversals_per_speed = 2.0;  // back-and-forth periods at each speed
  double run_speed_mm_s = 10.0;      // constant-speed runs
  double run_mm = 20.0;              // length of each run (0: none)
  double travel_mm = 80.0;           // the drift under the whole program (0: none) ...
  int drift_passes = 1;              // ... and how many times it goes there and back
  // false: the drift moves during the random moves and the sweep only, and stands still through
  // the reversals and the runs (their speeds are then the set ones both ways).
  bool drift_through_all = true;
  // Both > 0: the drift moves at these two speeds instead (mm/s; drift_passes and
  // drift_through_all are then unused): one under the random moves and the sweep, the other
  // under the reversals and the runs; it turns at 0 and travel_mm. For a program slow where the
  // periodic errors are read and above the Stribeck speed elsewhere (docs/ident.md).
  double drift_speed_random_mm_s = 0.0;
  double drift_speed_others_mm_s = 0.0;
  // With the two above: the drift's speed under the runs alone (0: it stands still there, so the
  // runs go at run_speed_mm_s both ways; < 0: drift_speed_others_mm_s).
  double drift_speed_runs_mm_s = -1.0;
  uint64_t seed = 1;
};

// Commanded positions (mm), one per sample, starting at 0.
std::vector<double> random_moves(const RandomMovesOptions& o);
std::vector<double> sine_sweep(const SineSweepOptions& o);
std::vector<double> calibration_program(const CalibrationProgramOptions& o);

}  // namespace feedloop::ident
