// Slip detection with a settle wait and whole-cycle rounding (see slip_detector.hpp).
#include "drivers/device/slip_detector.hpp"

#include <cmath>

#include "drivers/device/saturate.hpp"

namespace feedloop::device {

void SlipDetector::configure(float threshold_nm, float cycle_nm, float settle_s, float baseline_s) {
  baseline_s_ = baseline_s;
  threshold_nm_ = threshold_nm;
  cycle_nm_ = cycle_nm;
  settle_s_ = settle_s;
}

void SlipDetector::reset() {
  total_nm_ = d_nm_ = pending_s_ = baseline_nm_ = 0.0f;
  lag_.reset();
  pending_ = false;
  count_ = 0;
}

SlipEvent SlipDetector::update(float motor_minus_encoder_nm, float expected_deflection_nm,
                               float dt_s, float speed_nm_s) {
  SlipEvent ev;
  if (!std::isfinite(speed_nm_s)) speed_nm_s = 0.0f;  // no lag taken off a speed that is not one
  const float d_raw = motor_minus_encoder_nm - expected_deflection_nm - total_nm_;
  // The lag learns from d within the threshold with the lag learned so far (lag_learner.hpp).
  lag_.learn((d_raw - baseline_nm_) * 1e-6f, speed_nm_s * 1e-6f, dt_s, threshold_nm_ * 1e-6f);
  const float lag_nm = lag_.lag_s() * speed_nm_s;
  const float d = d_raw - baseline_nm_ - lag_nm;
  d_nm_ = d;
  if (d <= threshold_nm_ && d >= -threshold_nm_) {
    pending_ = false;  // back under the threshold: a transient deflection, not a slip
    if (baseline_s_ > 0.0f && dt_s > 0.0f)
      baseline_nm_ += dt_s / (baseline_s_ + dt_s) * (d_raw - lag_nm - baseline_nm_);
    return ev;
  }
  if (!pending_) {
    pending_ = true;
    pending_s_ = 0.0f;
    return ev;
  }
  pending_s_ += dt_s;
  if (pending_s_ < settle_s_) return ev;
  float size = d;
  if (cycle_nm_ > 0.0f) {
    const float c = d / cycle_nm_;
    const int32_t cycles = round_saturate_i32(c);
    // Beyond the threshold but less than half a cycle, or not near a whole cycle: keep watching
    // (a slip that is one shows as a whole cycle once the transient beside it has passed).
    const float off = c - static_cast<float>(cycles);
    if (cycles == 0 || off > kSlipCycleTolerance || off < -kSlipCycleTolerance) return ev;
    size = static_cast<float>(cycles) * cycle_nm_;
    ev.cycles = cycles;
  }
  pending_ = false;
  lag_.pause(kLagQuietAfterSlipS);
  total_nm_ += size;
  ++count_;
  d_nm_ = d - size;
  ev.happened = true;
  ev.size_nm = size;
  return ev;
}

}  // namespace feedloop::device
