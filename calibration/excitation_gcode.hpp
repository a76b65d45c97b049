// The calibration program as G-code (issue 15, item 5): what `feedloop calibrate` runs on a printer
// through its daemon, so the planner, the step pipeline and the loops run it as any print, and the
// recording of that print is the identification's trace (recorder/trace_export.hpp).
//
// It has the sections of ident::calibration_program (ident/excitation.hpp), written as moves the
// planner can take at the axis's acceleration limit instead of as samples:
//   1. random small moves (thesis App. D.3): steps of step_min..step_max mm, each followed by a
//      dwell (G4) of dwell_min..dwell_max s: the baseline;
//   2. a sweep of back-and-forth moves whose half period falls exponentially from 1/(2 f_start)
//      to 1/(2 f_end): resonances. A move of d mm taken in half a period tau = 1 / (2 f) at
//      constant acceleration needs a = 4 d / tau^2 = 16 d f^2, so d = min(2 amplitude,
//      accel / (16 f^2)) (Klipper's resonance test shrinks its amplitude the same way);
//   3. reversals of reversal_span mm at each of reversal_speeds: friction against backlash;
//   4. constant-speed runs of run_mm forward and back: periodic position errors, direction.
// Each cycle places its sections at bases spread over `travel_mm` (forward on even cycles, back
// on odd ones) so position-dependent effects are seen across the travel.
#pragma once

#include <cstdint>
#include <string>

namespace feedloop::calibration {

struct ExcitationGcodeOptions {
  char axis = 'X';                 // the axis letter the program moves (X or Y)
  double start_mm = 60.0;          // the axis position it starts from (and the travel's low end)
  double travel_mm = 80.0;         // the sections' bases span [start, start + travel]
  double accel_mm_s2 = 3000.0;     // the planner's limit on this axis (sizes the sweep)
  double max_speed_mm_s = 150.0;   // random moves' and travels' feed rate
  int cycles = 3;
  double random_s = 6.0;
  double step_min_mm = 0.01, step_max_mm = 0.08;
  double dwell_min_s = 0.03, dwell_max_s = 0.15;
  double sweep_s = 6.0;
  double sweep_f_start_hz = 5.0, sweep_f_end_hz = 150.0;
  double sweep_amplitude_mm = 0.03;
  double reversal_span_mm = 1.0;
  double reversal_speeds_mm_s[3] = {2.0, 5.0, 12.0};
  int reversals_per_speed = 2;
  double run_speed_mm_s = 10.0;
  double run_mm = 20.0;
  uint64_t seed = 1;
};

// The program: G90, a move to the start, the cycles, a final M400. Lines end in '\n'.
std::string excitation_gcode(const ExcitationGcodeOptions& o);

}  // namespace feedloop::calibration
