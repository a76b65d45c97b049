// PI law with a rate clamp and conditional integration (see pi_controller.hpp; thesis Sect. 4.6).
#include "control/pi_controller.hpp"

#include <algorithm>  // std::clamp
#include <cmath>      // std::isfinite, std::isnan
#include <string>

namespace feedloop::control {

Status PiController::configure(const PiParams& params) {
  auto bad = [](const std::string& what) { return Status(Error{"PI controller: " + what, {}}); };
  if (!std::isfinite(params.kp) || params.kp < 0.0) return bad("kp must be finite and >= 0");
  if (!std::isfinite(params.ki_per_s) || params.ki_per_s < 0.0)
    return bad("ki_per_s must be finite and >= 0");
  if (!std::isfinite(params.period_s) || params.period_s <= 0.0) return bad("period_s must be > 0");
  if (std::isnan(params.max_correction_mm_s) || params.max_correction_mm_s <= 0.0)
    return bad("max_correction_mm_s must be > 0 (infinity: no clamp)");
  if (std::isnan(params.integral_limit_mm) || params.integral_limit_mm <= 0.0)
    return bad("integral_limit_mm must be > 0 (infinity: unbounded)");
  p_ = params;
  max_step_mm_ = p_.max_correction_mm_s * p_.period_s;
  reset();
  return Status::Ok();
}

double PiController::update(double error_mm) { return update(error_mm, p_.period_s); }

double PiController::update(double error_mm, double dt_s) {
  if (!std::isfinite(error_mm)) return u_prev_mm_;  // the encoder guard reports the sensor
  double max_step_mm = max_step_mm_;
  if (!std::isfinite(dt_s) || dt_s <= 0.0) {
    dt_s = p_.period_s;
  } else if (dt_s != p_.period_s) {
    max_step_mm = p_.max_correction_mm_s * dt_s;
  }
  last_error_mm_ = error_mm;
  // Thesis Sect. 4.6: I[k] = I[k-1] + K_I e[k] (t[k] - t[k-1]), bounded.
  const double integral_try_mm =
      std::clamp(integral_mm_ + p_.ki_per_s * error_mm * dt_s, -p_.integral_limit_mm,
                 p_.integral_limit_mm);
  const double u_want_mm = offset_mm_ + p_.kp * error_mm + integral_try_mm;
  double u_mm = u_want_mm;
  saturated_ = 0;
  if (u_want_mm - u_prev_mm_ > max_step_mm) {
    u_mm = u_prev_mm_ + max_step_mm;
    saturated_ = 1;
  } else if (u_want_mm - u_prev_mm_ < -max_step_mm) {
    u_mm = u_prev_mm_ - max_step_mm;
    saturated_ = -1;
  }
  if (saturated_ != 0) ++saturated_count_;
  // Conditional integration: while the output is clamped, integrate only towards unclamping.
  const double d_integral_mm = integral_try_mm - integral_mm_;
  const bool winds_up = (saturated_ > 0 && d_integral_mm > 0.0) || (saturated_ < 0 && d_integral_mm < 0.0);
  if (!(p_.anti_windup && winds_up)) integral_mm_ = integral_try_mm;
  u_prev_mm_ = u_mm;
  return u_mm;
}

bool PiController::set_gains(double kp, double ki_per_s) {
  if (!std::isfinite(kp) || kp < 0.0 || !std::isfinite(ki_per_s) || ki_per_s < 0.0) return false;
  // u = offset + K_P e + I: keep it for e = the last error (not clamped by the integral limit,
  // which would bring the bump back).
  integral_mm_ += (p_.kp - kp) * last_error_mm_;
  p_.kp = kp;
  p_.ki_per_s = ki_per_s;
  return true;
}

void PiController::reset() {
  last_error_mm_ = 0.0;
  integral_mm_ = 0.0;
  offset_mm_ = 0.0;
  u_prev_mm_ = 0.0;
  saturated_ = 0;
  saturated_count_ = 0;
}

void PiController::shift(double shift_mm) {
  if (!std::isfinite(shift_mm)) return;
  offset_mm_ += shift_mm;
  u_prev_mm_ += shift_mm;
}

}  // namespace feedloop::control
