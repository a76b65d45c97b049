// Slip detection with a settle wait and whole-cycle rounding (see lost_step_detector.hpp).
#include "control/lost_step_detector.hpp"

#include <cmath>   // std::abs, std::llround, std::isfinite
#include <string>

namespace feedloop::control {

Status LostStepDetector::configure(const LostStepParams& params) {
  auto bad = [](const char* what) { return Status(Error{std::string("lost-step detector: ") + what, {}}); };
  if (!std::isfinite(params.threshold_mm) || params.threshold_mm <= 0.0)
    return bad("threshold_mm must be > 0");
  if (!std::isfinite(params.full_step_mm) || params.full_step_mm < 0.0)
    return bad("full_step_mm must be >= 0 (0: unknown)");
  if (params.full_steps_per_cycle < 1) return bad("full_steps_per_cycle must be >= 1");
  if (params.settle_periods < 1) return bad("settle_periods must be >= 1");
  if (!std::isfinite(params.period_s) || params.period_s <= 0.0) return bad("period_s must be > 0");
  const double cycle_mm = params.full_step_mm * params.full_steps_per_cycle;
  if (cycle_mm > 0.0 && cycle_mm <= 2.0 * params.threshold_mm)
    return bad("a slip cycle (full_steps_per_cycle x full_step_mm) must exceed 2 x threshold_mm");
  p_ = params;
  cycle_mm_ = cycle_mm;
  settle_s_ = params.settle_periods * params.period_s;
  reset();
  return Status::Ok();
}

void LostStepDetector::reset() {
  total_mm_ = 0.0;
  d_mm_ = 0.0;
  count_ = 0;
  beyond_ = false;
  beyond_s_ = 0.0;
}

std::optional<LostStepEvent> LostStepDetector::update(double motor_mm, double encoder_mm,
                                                      double expected_deflection_mm, double dt_s) {
  const double d = motor_mm - encoder_mm - expected_deflection_mm - total_mm_;
  if (!std::isfinite(d)) return std::nullopt;  // the encoder guard reports the sensor
  d_mm_ = d;
  if (std::abs(d) <= p_.threshold_mm) {
    beyond_ = false;  // under the threshold (again): a transient, not a slip
    return std::nullopt;
  }
  if (!(dt_s > 0.0) || !std::isfinite(dt_s)) dt_s = p_.period_s;
  if (!beyond_) {  // crossed somewhere since the previous sample: the wait starts here
    beyond_ = true;
    beyond_s_ = 0.0;
  } else if (beyond_s_ < settle_s_) {
    beyond_s_ += dt_s;
  }
  constexpr double kTimeEpsS = 1e-9;  // sums of periods are not exact
  if (beyond_s_ + kTimeEpsS < settle_s_) return std::nullopt;
  // Settled: round to whole cycles of the torque law when the step length is known.
  double size_mm = d;
  std::int64_t full_steps = 0;
  if (cycle_mm_ > 0.0) {
    const std::int64_t cycles = std::llround(d / cycle_mm_);
    // Beyond the threshold but not a slip, or not near a whole cycle (a model's error, not the
    // rotor falling into the next equilibrium): keep watching.
    const double off = d / cycle_mm_ - static_cast<double>(cycles);
    if (cycles == 0 || std::abs(off) > kSlipCycleTolerance) return std::nullopt;
    size_mm = static_cast<double>(cycles) * cycle_mm_;
    full_steps = cycles * p_.full_steps_per_cycle;
  }
  beyond_ = false;
  total_mm_ += size_mm;
  ++count_;
  d_mm_ = d - size_mm;
  return LostStepEvent{size_mm, full_steps, count_, total_mm_};
}

}  // namespace feedloop::control
