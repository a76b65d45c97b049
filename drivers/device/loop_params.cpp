// Validation of the device loop's parameters (see loop_params.hpp).
#include "drivers/device/loop_params.hpp"

#include <cmath>  // std::isfinite

namespace feedloop::device {

namespace {
bool positive(float x) { return std::isfinite(x) && x > 0.0f; }
}  // namespace

const char* loop_param_error_name(LoopParamError e) {
  switch (e) {
    case LoopParamError::kOk: return "ok";
    case LoopParamError::kPeriod: return "control period is 0";
    case LoopParamError::kGeometry: return "nm per encoder count or per step is 0";
    case LoopParamError::kGains: return "kp or ki negative or not finite";
    case LoopParamError::kLimits: return "a correction clamp, rate, following-error limit, speed or margin is not > 0";
    case LoopParamError::kSlip: return "slip threshold not > 0, slip cycle not > 2 x threshold, or settle time < 0";
    case LoopParamError::kStop: return "stop deceleration not > 0";
    case LoopParamError::kModel: return "deflection model terms not finite or filter time < 0";
    case LoopParamError::kHysteresis: return "reversal hysteresis not in [0, 4] steps";
  }
  return "unknown";
}

LoopParamError validate_loop_params(const LoopParams& p) {
  if (!p.enabled) return LoopParamError::kOk;
  if (p.period_ticks == 0) return LoopParamError::kPeriod;
  if (p.nm_per_count_q16 == 0 || p.nm_per_step_q16 == 0) return LoopParamError::kGeometry;
  if (!std::isfinite(p.kp) || p.kp < 0.0f || !std::isfinite(p.ki_per_s) || p.ki_per_s < 0.0f)
    return LoopParamError::kGains;
  if (!positive(p.max_correction_nm) || !positive(p.max_correction_rate_nm_s) ||
      !positive(p.max_following_error_nm) || !positive(p.max_speed_nm_s) || !positive(p.encoder_margin_nm))
    return LoopParamError::kLimits;
  if (!positive(p.slip_threshold_nm) || !std::isfinite(p.slip_cycle_nm) || p.slip_cycle_nm < 0.0f ||
      (p.slip_cycle_nm > 0.0f && p.slip_cycle_nm <= 2.0f * p.slip_threshold_nm) || !std::isfinite(p.slip_settle_s) ||
      p.slip_settle_s < 0.0f)
    return LoopParamError::kSlip;
  if (!positive(p.stop_decel_nm_s2)) return LoopParamError::kStop;
  if (!std::isfinite(p.deflection_s2) || !std::isfinite(p.deflection_s) || !std::isfinite(p.accel_filter_s) ||
      p.accel_filter_s < 0.0f)
    return LoopParamError::kModel;
  if (!(p.reversal_hysteresis_steps >= 0.0f && p.reversal_hysteresis_steps <= 4.0f))
    return LoopParamError::kHysteresis;
  return LoopParamError::kOk;
}

}  // namespace feedloop::device
