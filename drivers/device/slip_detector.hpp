// Skipped-step detection on the device (control/lost_step_detector.hpp, closed-loop-gantry
// thesis Sect. 5.3-5.4), per control tick:
//   d[k] = motor[k] - y[k] - deflection_model[k] - S[k-1]
// motor = every executed step (host's and the loop's) x nm/step, y = encoder, S = the slips
// already reported. |d| beyond the threshold for settle_s of MCU time (not a count of ticks: the
// carriage rings for the same time at 1 or 10 kHz) confirms a slip, sized from d then; when
// the torque law's period (4 full steps) is known the size is rounded to whole cycles (a stepper
// that slips falls into the next equilibrium, sim/gantry_axis.hpp). The size is the recovery: the
// loop shifts its correction by it (LoopPi::shift), so the motor re-synchronises with the
// carriage, and it is added to S so one slip is reported once.
// A slow baseline (time constant baseline_s, frozen while a slip is pending) is taken off d
// first: a slip is a sudden offset, while a steps/mm error, a belt that stretches with its length
// or friction the model lacks make d drift slowly (the host-side detector's residual baseline,
// control/lost_step_detector.hpp). Without it a 1 % scale error reads as a slip every 30 mm.
// A lag the model lacks (an encoder that reports the carriage late: a transport delay nobody
// declared) makes d proportional to the reference's speed instead, d = tau v; a slip does not
// depend on the speed. So tau is learned too (lag_learner.hpp) and tau v is taken off d; it learns
// from every sample whose d, with the lag learned so far, is under the threshold (least squares
// fits a pure delay's first move as it goes, so d stays under), and not for kLagQuietAfterSlipS
// after a slip. Without it an 8 ms encoder delay read as 48 slips on the thesis's small star at
// 6000 mm/s^2 (first simulator); each "recovery" moved the carriage by a whole cycle.
// docs/decisions.md, "A lag the model lacks is no slip".
// Owner: the axis loop. No heap, no exceptions.
#pragma once

#include <cstdint>

#include "drivers/device/lag_learner.hpp"

namespace feedloop::device {

// A confirmed d is a slip only within this fraction of a torque-law cycle of a whole number of
// them: the rotor falls into the next equilibrium, so a slip moves d by whole cycles, while a
// feedforward model's error moves it by any amount. A model of the second simulator's friction
// draw 1 (X: 3 N of LuGre friction, the springs' roles swapped by the fit) held d at 0.35-0.45 of
// a cycle for 30 ms on the thesis's large star: rounded to one cycle, the recovery moved the
// carriage by 0.68 mm, and back 170 ms later (e_t 0.0411 mm against 0.0372 with the rule).
inline constexpr float kSlipCycleTolerance = 0.25f;

struct SlipEvent {
  bool happened = false;
  float size_nm = 0.0f;     // signed: + when the rotor fell behind moving + (steps to make up)
  int32_t cycles = 0;       // size in torque-law cycles (0 when the cycle is unknown)
};

class SlipDetector {
 public:
  void configure(float threshold_nm, float cycle_nm, float settle_s, float baseline_s = 0.1f);
  void reset();
  // dt_s: MCU time since the previous update; speed_nm_s: the reference's speed v (for the
  // learned lag; 0: no lag taken off).
  SlipEvent update(float motor_minus_encoder_nm, float expected_deflection_nm, float dt_s,
                   float speed_nm_s = 0.0f);
  // A slip is suspected (|d| beyond the threshold, waiting for the settle time).
  bool pending() const { return pending_; }

  float discrepancy_nm() const { return d_nm_; }
  float total_nm() const { return total_nm_; }
  float learned_lag_s() const { return lag_.lag_s(); }
  uint32_t count() const { return count_; }

 private:
  float threshold_nm_ = 0.0f, cycle_nm_ = 0.0f;
  float settle_s_ = 0.0f;
  float baseline_s_ = 0.1f, baseline_nm_ = 0.0f;
  LagLearner lag_;  // tau
  float total_nm_ = 0.0f, d_nm_ = 0.0f;
  float pending_s_ = 0.0f;
  bool pending_ = false;
  uint32_t count_ = 0;
};

}  // namespace feedloop::device
