// An excitation program (ident/excitation.hpp) recorded on the simulated gantry axis: the
// commanded positions run on sim::GantryAxis through the ideal sim::StepDriver, commanded steps
// and encoder sampled at the program's rate, as a trace CSV v1 (ident/trace.hpp).
// A simulated experiment: it uses both the plant (sim/) and identification's types (ident/), so it
// lives above both (feedloop_sim_experiments); ident/ itself never reaches into sim/.
#pragma once

#include <string>
#include <vector>

#include "core/result.hpp"
#include "ident/trace.hpp"
#include "sim/gantry_params.hpp"

namespace feedloop::sim {

// Runs the program on a GantryAxis built from `params` (steps at params' mm per step) and returns a
// one-axis trace named `axis_name`: time_s = k / rate, cmd = steps sent x mm per step, meas =
// encoder counts x mm per count (both relative to power-on). Metadata: sample_rate_hz, source=sim.
// Errors: invalid parameters, a rate <= 0, an empty program.
Result<ident::Trace> record_gantry_trace(const GantryAxisParams& params,
                                         const std::vector<double>& cmd_mm, double sample_rate_hz,
                                         const std::string& axis_name);

}  // namespace feedloop::sim
