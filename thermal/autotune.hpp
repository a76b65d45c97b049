// PID autotune by the relay method (M303), as Klipper's PID_CALIBRATE (klippy/extras/
// pid_calibrate.py) and Marlin's M303 do it: full power until the temperature passes the target,
// off until it falls delta_c below it, repeated; the oscillation's amplitude a and period Tu give
// the ultimate gain Ku = 4 d / (pi a) (d: the relay's half swing, max_power/2) and the classic
// Ziegler-Nichols gains Kp = 0.6 Ku, Ti = Tu / 2, Td = Tu / 8 (reported per 255 of power, the
// Marlin/Klipper units). No allocation.
#pragma once

#include <cstdint>

#include "thermal/pid.hpp"

namespace feedloop::thermal {

struct AutotuneParams {
  double target_c = 200.0;
  double delta_c = 5.0;  // Klipper's TUNE_PID_DELTA
  double max_power = 1.0;
  int cycles = 5;             // Marlin's M303 C default
  double timeout_s = 1200.0;  // give up (Marlin: 20 min)
  double max_temp_c =
      0.0;  // > 0: abort above this (Marlin: "PID Autotune failed! Temperature too high")
};

enum class AutotuneState : uint8_t { kRunning, kDone, kTimedOut, kTooHot };

class RelayAutotune {
 public:
  explicit RelayAutotune(const AutotuneParams& p);
  // One update; returns the power to apply.
  double update(double t_s, double temp_c);
  AutotuneState state() const { return state_; }
  // Valid once kDone.
  PidParams result() const { return result_; }
  double ultimate_gain() const { return ku_; }
  double ultimate_period_s() const { return tu_s_; }
  int peaks() const { return npeaks_; }

 private:
  void finish();
  AutotuneParams p_;
  AutotuneState state_ = AutotuneState::kRunning;
  bool heating_ = true;
  bool started_ = false;
  double t0_s_ = 0.0;
  double peak_c_ = 0.0, peak_t_s_ = 0.0;
  static constexpr int kMaxPeaks = 64;
  double peak_temp_[kMaxPeaks] = {}, peak_time_[kMaxPeaks] = {};
  int npeaks_ = 0;
  PidParams result_{};
  double ku_ = 0.0, tu_s_ = 0.0;
};

}  // namespace feedloop::thermal
