// Slip detection with a settle wait and whole-cycle rounding (see slip_detector.hpp).
#include "drivers/device/slip_detector.hpp"

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
  svv_ = svd_ = lag_s_ = quiet_s_ = 0.0f;
  pending_ = false;
  count_ = 0;
}

void SlipDetector::learn_lag_(float d_raw_nm, float dt_s, float speed_nm_s) {
  if (quiet_s_ > 0.0f) {
    quiet_s_ -= dt_s;
    return;
  }
  // Least squares of d (less the baseline) on v, in mm and s: tau = sum v d dt / (sum v^2 dt +
  // prior).
  const float v_mm_s = speed_nm_s * 1e-6f, d_mm = (d_raw_nm - baseline_nm_) * 1e-6f;
  const float keep = 1.0f - dt_s / (kLagMemoryS + dt_s);
  svv_ = keep * svv_ + v_mm_s * v_mm_s * dt_s;
  svd_ = keep * svd_ + v_mm_s * d_mm * dt_s;
  const float lag = svd_ / (svv_ + kLagPriorMm2S);
  lag_s_ =
      lag > kMaxLearnedLagS ? kMaxLearnedLagS : (lag < -kMaxLearnedLagS ? -kMaxLearnedLagS : lag);
}

SlipEvent SlipDetector::update(float motor_minus_encoder_nm, float expected_deflection_nm,
                               float dt_s, float speed_nm_s) {
  SlipEvent ev;
  const float d_raw = motor_minus_encoder_nm - expected_deflection_nm - total_nm_;
  if (dt_s > 0.0f) learn_lag_(d_raw, dt_s, speed_nm_s);
  const float lag_nm = lag_s_ * speed_nm_s;
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
  quiet_s_ = kLagQuietAfterSlipS;
  total_nm_ += size;
  ++count_;
  d_nm_ = d - size;
  ev.happened = true;
  ev.size_nm = size;
  return ev;
}

}  // namespace feedloop::device
