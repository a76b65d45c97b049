// An excitation program recorded on the second simulator's axis: the same shape as
// sim/experiments/gantry_recording.hpp, with a step generator of its own. The program (mm
// relative to the start, one value per sample) is interpolated linearly between samples and
// quantised to microsteps at every integration step (the staircase a step generator sends); the
// trace's cmd is the staircase at the sample times, meas the quantised encoder reading, both
// relative to power-on. Links ident/ for its types; plant2's physics does not.
#pragma once

#include <string>
#include <vector>

#include "core/result.hpp"
#include "ident/trace.hpp"
#include "plant2/params.hpp"

namespace feedloop::plant2 {

// mm of commanded belt motion per microstep: 2 pi r / (4 n_r microsteps).
double mm_per_microstep(const StepperParams& s);

// Runs the program on an Axis2 built from `params` (at rest at params.start_m) and returns a
// one-axis trace named `axis_name`: time_s = k / rate, cmd_mm = microsteps commanded x mm per
// microstep, meas_mm = the encoder's quantised reading (both relative to the start).
// Metadata: sample_rate_hz, source=plant2. Errors: invalid parameters, a rate <= 0, an empty
// program.
Result<ident::Trace> record_axis2_trace(const Axis2Params& params,
                                        const std::vector<double>& cmd_mm, double sample_rate_hz,
                                        const std::string& axis_name);

}  // namespace feedloop::plant2
