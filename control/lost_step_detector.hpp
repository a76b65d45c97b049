// Skipped-step detection for one joint (closed-loop-gantry-thesis Sect. 5.3-5.4): the motor
// position the host believes in (steps sent x mm/step) is compared with the encoder after
// removing the deflection the model expects between motor and carriage (belt stretch; 0 without
// a model):
//   d[k] = q_motor[k] - q_enc[k] - delta_model[k] - S[k-1]
// with S the sum of the slips already reported. A stepper that slips falls back to another
// equilibrium of its torque law, which repeats every 4 full steps (sim/gantry_axis.hpp,
// lost_full_steps()), so when the full-step length is known the slip is rounded to whole cycles
// lambda = 4 x full_step_mm: size = lambda round(d / lambda). Once |d| exceeds the threshold the
// detector waits settle_periods x period_s of time (the rotor rings after a jump), then reports one
// event of that size and adds it to S, so one slip is reported once; if |d| falls back under the
// threshold within the wait it was a transient deflection, not a slip. The wait is counted in the
// time between the updates' samples (dt_s), not in updates: a late period is not a longer wait. The event's size is the shift the
// motor command needs to recover the position (PiController::shift): positive when the rotor has
// fallen behind in the + direction (the motor must make up the steps in +).
// Owner: servo thread. configure() validates; update() and reset() are RT-safe.
#pragma once

#include <cstdint>
#include <optional>

#include "core/result.hpp"

namespace feedloop::control {

// A settled d is a slip only within this fraction of a cycle of a whole number of cycles (the
// rotor falls into the next equilibrium; a model's error moves d by any amount):
// drivers/device/slip_detector.hpp has the case.
inline constexpr double kSlipCycleTolerance = 0.25;

struct LostStepParams {
  double threshold_mm = 0.3;    // |d| beyond this: a slip is suspected
  double full_step_mm = 0.0;    // length of one full step; 0: unknown, slips are not rounded
  int full_steps_per_cycle = 4; // the stepper's torque law repeats every 4 full steps
  int settle_periods = 5;       // wait after |d| crosses the threshold before reporting,
  double period_s = 1e-3;       //   settle_periods x period_s of sample time (update() without dt_s: one period)
};

struct LostStepEvent {
  double size_mm = 0.0;          // signed; = the recovery shift of the motor command
  std::int64_t full_steps = 0;   // size in full steps (0 when full_step_mm is unknown)
  std::int64_t count = 0;        // events so far, this one included
  double total_mm = 0.0;         // S: every reported slip summed
};

class LostStepDetector {
 public:
  // Errors: threshold not > 0, full_step_mm < 0, a cycle (lambda) not larger than 2 x threshold
  // (a half-cycle residual would re-trigger), settle_periods < 1, period_s not > 0.
  Status configure(const LostStepParams& params);

  // RT-safe. One period: the motor position (steps sent x mm/step), the encoder position (same
  // coordinates) and the model's expected motor - carriage deflection (mm). An event when a slip
  // has been confirmed this period. dt_s: the time since the previous update's sample (not > 0 or
  // not finite: one period_s).
  std::optional<LostStepEvent> update(double motor_mm, double encoder_mm,
                                      double expected_deflection_mm = 0.0, double dt_s = 0.0);

  // RT-safe. Forget every reported slip (after re-homing / re-basing the motor position).
  void reset();

  double discrepancy_mm() const { return d_mm_; }   // d[k] of the last update
  double total_mm() const { return total_mm_; }
  std::int64_t count() const { return count_; }
  bool pending() const { return beyond_; }
  const LostStepParams& params() const { return p_; }

 private:
  LostStepParams p_{};
  double cycle_mm_ = 0.0;   // lambda, 0 when unknown
  double total_mm_ = 0.0;   // S
  double d_mm_ = 0.0;
  std::int64_t count_ = 0;
  double settle_s_ = 0.0;   // settle_periods x period_s
  bool beyond_ = false;     // |d| is beyond the threshold since ...
  double beyond_s_ = 0.0;   // ... this much sample time
};

}  // namespace feedloop::control
