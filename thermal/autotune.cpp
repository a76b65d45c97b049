#include "thermal/autotune.hpp"

#include <cmath>
#include <numbers>

namespace feedloop::thermal {

RelayAutotune::RelayAutotune(const AutotuneParams& p) : p_(p) {}

double RelayAutotune::update(double t_s, double temp_c) {
  if (state_ != AutotuneState::kRunning) return 0.0;
  if (!started_) {
    started_ = true;
    t0_s_ = t_s;
    peak_c_ = temp_c;
    peak_t_s_ = t_s;
  }
  if (p_.max_temp_c > 0 && temp_c > p_.max_temp_c) {
    state_ = AutotuneState::kTooHot;
    return 0.0;
  }
  if (t_s - t0_s_ > p_.timeout_s) {
    state_ = AutotuneState::kTimedOut;
    return 0.0;
  }
  // Track the extreme of the current half cycle (max while off after heating, min while heating).
  if (heating_) {
    if (temp_c < peak_c_) {
      peak_c_ = temp_c;
      peak_t_s_ = t_s;
    }
    if (temp_c >= p_.target_c) {  // switch off: record the trough of the heating half
      heating_ = false;
      if (npeaks_ < kMaxPeaks) {
        peak_temp_[npeaks_] = peak_c_;
        peak_time_[npeaks_] = peak_t_s_;
        ++npeaks_;
      }
      peak_c_ = temp_c;
      peak_t_s_ = t_s;
    }
  } else {
    if (temp_c > peak_c_) {
      peak_c_ = temp_c;
      peak_t_s_ = t_s;
    }
    if (temp_c <= p_.target_c - p_.delta_c) {  // switch on: record the crest
      heating_ = true;
      if (npeaks_ < kMaxPeaks) {
        peak_temp_[npeaks_] = peak_c_;
        peak_time_[npeaks_] = peak_t_s_;
        ++npeaks_;
      }
      peak_c_ = temp_c;
      peak_t_s_ = t_s;
    }
  }
  // Peaks alternate trough, crest, trough, ... The first trough is the start temperature and the
  // first crest the overshoot of the first heat-up: skip them (Klipper skips the first cycles too).
  if (npeaks_ >= 2 * p_.cycles + 3) finish();
  return heating_ ? p_.max_power : 0.0;
}

void RelayAutotune::finish() {
  // Average over the last `cycles` full cycles: amplitude = half the crest-trough swing, period =
  // crest-to-crest time.
  double amp_sum = 0.0, period_sum = 0.0;
  int n = 0;
  for (int i = npeaks_ - 1; i >= 3 && n < p_.cycles; --i) {
    if (i % 2 == 1) {  // crest at i, troughs at i-1
      amp_sum += 0.5 * (peak_temp_[i] - peak_temp_[i - 1]);
      period_sum += peak_time_[i] - peak_time_[i - 2];
      ++n;
    }
  }
  if (n == 0 || amp_sum <= 0) {
    state_ = AutotuneState::kTimedOut;
    return;
  }
  const double a = amp_sum / n;
  tu_s_ = period_sum / n;
  ku_ = 4.0 * (p_.max_power / 2.0) / (std::numbers::pi * a);  // power fraction per C
  const double kp = 0.6 * ku_, ti = 0.5 * tu_s_, td = 0.125 * tu_s_;
  result_.kp = kp * 255.0;
  result_.ki = kp / ti * 255.0;
  result_.kd = kp * td * 255.0;
  result_.max_power = p_.max_power;
  state_ = AutotuneState::kDone;
}

}  // namespace feedloop::thermal
