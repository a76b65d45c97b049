// Timestamp-based encoder plausibility (see encoder_plausibility.hpp).
#include "drivers/device/encoder_plausibility.hpp"

namespace feedloop::device {

void EncoderPlausibility::configure(float max_speed_nm_s, float margin_nm, uint32_t reject_limit,
                                    float clock_hz) {
  max_speed_nm_per_tick_ = max_speed_nm_s / clock_hz;
  margin_nm_ = margin_nm;
  limit_ = reject_limit < 1 ? 1 : reject_limit;
}

void EncoderPlausibility::reset() {
  have_good_ = false;
  in_row_ = 0;
  last_jump_nm_ = last_allowed_nm_ = 0.0f;
}

EncoderVerdict EncoderPlausibility::check(int64_t clock, int64_t y_nm) {
  if (!have_good_) {
    have_good_ = true;
    good_clock_ = clock;
    good_nm_ = y_nm;
    return EncoderVerdict::kGood;
  }
  const int64_t d = y_nm - good_nm_;
  last_jump_nm_ = static_cast<float>(d < 0 ? -d : d);
  const int64_t dt = clock > good_clock_ ? clock - good_clock_ : 0;
  last_allowed_nm_ = max_speed_nm_per_tick_ * static_cast<float>(dt) + margin_nm_;
  if (last_jump_nm_ <= last_allowed_nm_) {
    good_clock_ = clock;
    good_nm_ = y_nm;
    in_row_ = 0;
    return EncoderVerdict::kGood;
  }
  ++in_row_;
  return in_row_ >= limit_ ? EncoderVerdict::kFault : EncoderVerdict::kRejected;
}

}  // namespace feedloop::device
