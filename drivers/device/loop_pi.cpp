// PI with output clamp and conditional integration (see loop_pi.hpp; thesis Sect. 4.6).
#include "drivers/device/loop_pi.hpp"

namespace feedloop::device {

void LoopPi::configure(float kp, float ki_per_s, float max_output_nm) {
  kp_ = kp;
  ki_per_s_ = ki_per_s;
  max_nm_ = max_output_nm;
  reset();
}

void LoopPi::reset() {
  integral_nm_ = offset_nm_ = last_error_nm_ = last_p_error_nm_ = u_nm_ = 0.0f;
  saturated_ = 0;
}

float LoopPi::update(float error_nm, float dt_s, bool integrate, float p_band_nm) {
  last_error_nm_ = error_nm;
  const float p_error_nm = error_nm > p_band_nm
                               ? error_nm - p_band_nm
                               : (error_nm < -p_band_nm ? error_nm + p_band_nm : 0.0f);
  last_p_error_nm_ = p_error_nm;
  // Thesis Sect. 4.6: I[k] = I[k-1] + K_I e[k] (t[k] - t[k-1]).
  const float integral_try = integral_nm_ + (integrate ? ki_per_s_ * error_nm * dt_s : 0.0f);
  const float want = offset_nm_ + kp_ * p_error_nm + integral_try;
  // The recovery offset is outside the clamp: the clamp bounds what the PI adds to it.
  const float hi = offset_nm_ + max_nm_, lo = offset_nm_ - max_nm_;
  float u = want;
  saturated_ = 0;
  if (want > hi) {
    u = hi;
    saturated_ = 1;
  } else if (want < lo) {
    u = lo;
    saturated_ = -1;
  }
  const float d_integral = integral_try - integral_nm_;
  const bool winds_up = (saturated_ > 0 && d_integral > 0.0f) || (saturated_ < 0 && d_integral < 0.0f);
  if (!winds_up) integral_nm_ = integral_try;
  u_nm_ = u;
  return u;
}

void LoopPi::set_gains(float kp, float ki_per_s, float max_output_nm) {
  integral_nm_ += (kp_ - kp) * last_p_error_nm_;
  kp_ = kp;
  ki_per_s_ = ki_per_s;
  max_nm_ = max_output_nm;
}

void LoopPi::shift(float shift_nm) {
  offset_nm_ += shift_nm;
  u_nm_ += shift_nm;
}

}  // namespace feedloop::device
