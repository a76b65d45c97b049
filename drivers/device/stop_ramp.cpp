// Constant-deceleration stop (see stop_ramp.hpp).
#include "drivers/device/stop_ramp.hpp"

#include "drivers/device/saturate.hpp"

namespace feedloop::device {

void StopRamp::start(int64_t clock, int64_t p0_nm, float v0_nm_s, float decel_nm_s2, float clock_hz) {
  t0_ = clock;
  p0_nm_ = p0_nm;
  v0_ = v0_nm_s;
  a_signed_ = v0_nm_s >= 0.0f ? decel_nm_s2 : -decel_nm_s2;
  inv_hz_ = 1.0f / clock_hz;
  t_end_s_ = v0_nm_s / a_signed_;  // >= 0
  // Saturated: a tiny deceleration or a huge speed may give a duration beyond int64 ticks.
  end_clock_ = add_saturate_i64(clock, add_saturate_i64(saturate_i64(t_end_s_ * clock_hz), 1));
}

int64_t StopRamp::position_at(int64_t clock) const {
  float tau = static_cast<float>(clock - t0_) * inv_hz_;
  if (tau < 0.0f) tau = 0.0f;
  if (tau > t_end_s_) tau = t_end_s_;
  return add_saturate_i64(p0_nm_, saturate_i64(v0_ * tau - 0.5f * a_signed_ * tau * tau));
}

}  // namespace feedloop::device
