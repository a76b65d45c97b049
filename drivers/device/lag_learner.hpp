// A lag that a slip check's model lacks, learned from the data (docs/decisions.md, "A lag the
// model lacks is no slip"). An encoder that reports the carriage tau late (a transport delay, an
// interpolator's filter) that nobody declared makes motor - encoder read tau v beyond what the
// model expects; a slip does not depend on the speed. tau is the least-squares fit of the
// discrepancy d (less its slow baseline) on the reference's speed v over the last seconds of
// motion:
//   tau = sum v d dt / (sum v^2 dt + prior),   both sums decaying with time constant kLagMemoryS,
// the prior (20 mm/s)^2 x 5 ms pulling towards no lag, tau bounded to +-kMaxLearnedLagS. Least
// squares with a long memory is fast at first (a pure delay is fitted by the first move's first
// milliseconds) and then hard to move (a slip's few milliseconds weigh little against seconds of
// motion). It learns only from samples whose d, with the lag learned so far, is within the
// caller's slip threshold (a slip's d is never taken as a lag), and pause() stops the learning for
// a while (after a slip: the recovery rings the carriage at the print's speed).
// Used by the device loop's SlipDetector (float, on the MCU) and the host loop's residual check
// (engine/servo_control.cpp). Header-only; no heap, no exceptions.
#pragma once

#include <cmath>

namespace feedloop::device {

inline constexpr float kLagMemoryS = 2.0f;
inline constexpr float kLagPriorMm2S = 2.0f;  // (20 mm/s)^2 x 5 ms
inline constexpr float kMaxLearnedLagS = 0.05f;
inline constexpr float kLagQuietAfterSlipS = 0.3f;

class LagLearner {
 public:
  void reset() { svv_ = svd_ = lag_s_ = quiet_s_ = 0.0f; }
  // One sample: d (mm, less its baseline), the reference's speed (mm/s), the time since the last
  // sample (s, > 0), and the slip threshold (mm): a sample whose |d - tau v| is beyond it teaches
  // nothing.
  void learn(float d_mm, float v_mm_s, float dt_s, float threshold_mm) {
    if (!(dt_s > 0.0f) || !std::isfinite(d_mm) || !std::isfinite(v_mm_s) || !std::isfinite(dt_s))
      return;
    const float left_mm = d_mm - lag_s_ * v_mm_s;
    if (!(left_mm <= threshold_mm && left_mm >= -threshold_mm)) return;
    if (quiet_s_ > 0.0f) {
      quiet_s_ -= dt_s;
      return;
    }
    const float keep = 1.0f - dt_s / (kLagMemoryS + dt_s);
    svv_ = keep * svv_ + v_mm_s * v_mm_s * dt_s;
    svd_ = keep * svd_ + v_mm_s * d_mm * dt_s;
    const float lag = svd_ / (svv_ + kLagPriorMm2S);
    lag_s_ =
        lag > kMaxLearnedLagS ? kMaxLearnedLagS : (lag < -kMaxLearnedLagS ? -kMaxLearnedLagS : lag);
  }
  void pause(float s) { quiet_s_ = s; }
  float lag_s() const { return lag_s_; }

 private:
  float svv_ = 0.0f;  // sum v^2 dt, mm^2/s
  float svd_ = 0.0f;  // sum v d dt, mm^2
  float lag_s_ = 0.0f;
  float quiet_s_ = 0.0f;
};

}  // namespace feedloop::device
