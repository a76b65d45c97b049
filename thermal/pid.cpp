#include "thermal/pid.hpp"

#include <algorithm>

namespace feedloop::thermal {

void HeaterPid::reset() {
  have_prev_ = false;
  deriv_c_s_ = 0.0;
  integ_ = 0.0;
}

double HeaterPid::update(double t_s, double temp_c, double target_c) {
  if (target_c <= 0.0) {  // off: Klipper resets nothing, but a heater turned off starts afresh
    reset();
    return 0.0;
  }
  const double kp = p_.kp / 255.0, ki = p_.ki / 255.0, kd = p_.kd / 255.0;
  double dt = 0.0;
  if (have_prev_) {
    dt = std::max(t_s - prev_t_s_, 0.0);
    if (dt > 0.0) {
      const double d = (temp_c - prev_temp_c_) / dt;
      const double a = std::min(1.0, dt / std::max(p_.smooth_time_s, 1e-9));
      deriv_c_s_ = deriv_c_s_ + a * (d - deriv_c_s_);
    }
  }
  const double err = target_c - temp_c;
  double integ = integ_ + err * dt;
  const double integ_max = ki > 0 ? p_.max_power / ki : 0.0;
  integ = std::clamp(integ, 0.0, integ_max);
  const double raw = kp * err + ki * integ - kd * deriv_c_s_;
  const double out = std::clamp(raw, 0.0, p_.max_power);
  if (out == raw) integ_ = integ;  // anti-windup: integrate only while unsaturated
  prev_t_s_ = t_s;
  prev_temp_c_ = temp_c;
  have_prev_ = true;
  return out;
}

}  // namespace feedloop::thermal
