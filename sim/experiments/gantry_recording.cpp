// An excitation program recorded on the simulated gantry axis (see gantry_recording.hpp).
#include "sim/experiments/gantry_recording.hpp"

#include <cmath>

#include "sim/gantry_axis.hpp"
#include "sim/step_driver.hpp"

namespace feedloop::sim {

Result<ident::Trace> record_gantry_trace(const GantryAxisParams& params,
                                         const std::vector<double>& cmd_mm, double sample_rate_hz,
                                         const std::string& axis_name) {
  if (!(sample_rate_hz > 0.0)) return Error{"sample rate must be > 0", {}};
  if (cmd_mm.empty()) return Error{"empty excitation program", {}};
  auto axis = GantryAxis::create(params);
  if (!axis) return axis.error();
  GantryAxis& plant = axis.value();
  const double start_mm = params.initial_pos_mm;
  // Steps where the program's line crosses their thresholds, as the production step generator
  // times them (a recorded trace then has the command a real one has, docs/ident.md).
  StepDriver driver(plant, plant.mm_per_step(), start_mm, 0.0, StepTiming::threshold);
  ident::Trace trace;
  trace.metadata.emplace_back("sample_rate_hz",
                              std::to_string(static_cast<long>(std::lround(sample_rate_hz))));
  trace.metadata.emplace_back("source", "sim");
  ident::AxisTrace a{axis_name, {}, {}};
  a.cmd_mm.reserve(cmd_mm.size());
  a.meas_mm.reserve(cmd_mm.size());
  trace.time_s.reserve(cmd_mm.size());
  for (size_t k = 0; k < cmd_mm.size(); ++k) {
    const double t = static_cast<double>(k) / sample_rate_hz;
    if (k > 0) driver.update(t, start_mm + cmd_mm[k]);
    plant.advance_to(t);
    trace.time_s.push_back(t);
    a.cmd_mm.push_back(driver.commanded_mm() - start_mm);
    a.meas_mm.push_back(static_cast<double>(plant.read_encoder_counts(t)) *
                        plant.encoder_mm_per_count());
  }
  trace.axes.push_back(std::move(a));
  return trace;
}

}  // namespace feedloop::sim
