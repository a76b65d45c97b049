// Encoder plausibility on the device, judged on sample timestamps (MCU clock), not on a count of
// periods (the bug of control/encoder_guard.cpp: one late wake-up made a normal move a "jump"):
//   a sample y at clock t is implausible when |y - y_good| > v_max (t - t_good) + margin,
// with (t_good, y_good) the last accepted sample. A rejected sample is not used; the next one is
// judged against the same good sample over the longer time, so a legitimate move after a long
// gap between samples passes. reject_limit implausible samples in a row: a fault.
// Owner: the axis loop. No heap, no exceptions.
#pragma once

#include <cstdint>

namespace feedloop::device {

enum class EncoderVerdict : uint8_t { kGood, kRejected, kFault };

class EncoderPlausibility {
 public:
  void configure(float max_speed_nm_s, float margin_nm, uint32_t reject_limit, float clock_hz);
  void reset();
  EncoderVerdict check(int64_t clock, int64_t y_nm);

  bool have_good() const { return have_good_; }
  int64_t good_nm() const { return good_nm_; }
  int64_t good_clock() const { return good_clock_; }
  // Of the last check: the distance seen and the distance allowed (nm).
  float last_jump_nm() const { return last_jump_nm_; }
  float last_allowed_nm() const { return last_allowed_nm_; }
  uint32_t rejected_in_row() const { return in_row_; }

 private:
  float max_speed_nm_per_tick_ = 0.0f, margin_nm_ = 0.0f;
  uint32_t limit_ = 1;
  bool have_good_ = false;
  int64_t good_clock_ = 0, good_nm_ = 0;
  uint32_t in_row_ = 0;
  float last_jump_nm_ = 0.0f, last_allowed_nm_ = 0.0f;
};

}  // namespace feedloop::device
