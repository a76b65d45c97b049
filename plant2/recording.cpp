// An excitation program recorded on the second simulator's axis (see recording.hpp).
#include "plant2/recording.hpp"

#include <cmath>

#include "plant2/axis2.hpp"

namespace feedloop::plant2 {

double mm_per_microstep(const StepperParams& s) {
  constexpr double kTwoPi = 6.283185307179586;
  return 1e3 * kTwoPi * s.pulley_radius_m / (4.0 * s.rotor_teeth * s.microsteps);
}

Result<ident::Trace> record_axis2_trace(const Axis2Params& params,
                                        const std::vector<double>& cmd_mm, double sample_rate_hz,
                                        const std::string& axis_name) {
  if (!(sample_rate_hz > 0.0)) return Error{"sample rate must be > 0", {}};
  if (cmd_mm.empty()) return Error{"empty excitation program", {}};
  auto created = Axis2::create(params);
  if (!created) return created.error();
  Axis2& axis = created.value();
  const double step_mm = mm_per_microstep(params.stepper);
  auto staircase_mm = [step_mm](double c) { return std::round(c / step_mm) * step_mm; };
  const double period_s = 1.0 / sample_rate_hz;
  const int substeps = std::max(1, static_cast<int>(std::ceil(period_s / axis.max_step_s())));
  const double dt = period_s / substeps;

  ident::Trace trace;
  trace.metadata.emplace_back("sample_rate_hz",
                              std::to_string(static_cast<long>(std::lround(sample_rate_hz))));
  trace.metadata.emplace_back("source", "plant2");
  ident::AxisTrace a{axis_name, {}, {}};
  a.cmd_mm.reserve(cmd_mm.size());
  a.meas_mm.reserve(cmd_mm.size());
  trace.time_s.reserve(cmd_mm.size());
  const double start_mm = params.start_m * 1e3;
  const double c0 = cmd_mm.front();  // the program's first sample is where the axis rests
  for (size_t k = 0; k < cmd_mm.size(); ++k) {
    trace.time_s.push_back(static_cast<double>(k) * period_s);
    a.cmd_mm.push_back(staircase_mm(cmd_mm[k] - c0));
    a.meas_mm.push_back(axis.measured_quantised_m() * 1e3 - start_mm);
    if (k + 1 == cmd_mm.size()) break;
    // The program between samples, linear, sent as microsteps.
    const double from = cmd_mm[k] - c0;
    const double to = cmd_mm[k + 1] - c0;
    for (int i = 0; i < substeps; ++i) {
      const double w = static_cast<double>(i + 1) / substeps;
      const double u_mm = staircase_mm(from + w * (to - from));
      axis.step((start_mm + u_mm) * 1e-3, dt);
    }
  }
  trace.axes.push_back(std::move(a));
  return trace;
}

}  // namespace feedloop::plant2
