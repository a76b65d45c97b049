// The control law of the servo thread (closed-loop-gantry-thesis Sect. 4.6, Fig. 6), per command
// sample: the feedforward path F turns the planned joint trajectory r into motor commands u_ff
// (F = 1, an input shaper, or the LPV model inverse), and the PI controller C adds a correction
// from the encoder error e = r - x_e:
//
//   u[k] = F(r)[k] + C(e)[k],   C: u_c[k] = K_P e[k] + K_I sum_m e[m] (t[m] - t[m-1])   (thesis Sect. 4.6)
//
// the change of the correction clamped per period (max_correction_mm_s, "to keep the motor out of
// resonance"), with anti-windup. Lost steps (motor position vs encoder beyond a threshold) raise
// an event and shift the correction by the slip so the carriage returns to the path at the
// clamp's rate (thesis Sect. 5.3-5.4); an implausible or stale encoder or a following error
// beyond the limit stops motion with a message rather than chasing a bad sensor.
// RT-safe after construction: every call allocates nothing and locks nothing.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "config/machine_config.hpp"
#include "control/encoder_guard.hpp"
#include "control/feedforward.hpp"
#include "control/lost_step_detector.hpp"
#include "control/pi_controller.hpp"
#include "core/result.hpp"
#include "drivers/device/lag_learner.hpp"
#include "engine/telemetry_tap.hpp"
#include "model/discrete.hpp"

namespace feedloop::engine {

struct ServoControlParams {
  config::ControlConfig control;
  double period_s = 1e-3;
  std::array<bool, 4> has_encoder{};        // joints with an encoder (PI and guards act on these)
  std::array<double, 4> mm_per_full_step{};  // slips come in multiples of 4 full steps (0: unknown)
  std::array<std::string, 4> joint_names{};  // for the messages
  std::array<control::EncoderGuardParams, 4> guard{};  // per joint (the axis name is joint_names')
  // The carriage model per joint (motor command -> carriage, SI), for the lost-step detector's
  // expected position; none: the detector compares against the command.
  std::array<std::optional<model::StateSpace>, 4> carriage_model;
  double residual_baseline_s = 0.3;  // slow drifts of the model residual are not slips
  double lost_step_confirm_s = 0.015;  // the residual stays beyond the threshold this long
  double recovery_mm_s = 10.0;         // lost steps are made up at this speed (gently: the motor
                                       // that just slipped is at its torque limit)
};

class ServoControl {
 public:
  // `feedforward` may be nullptr (F = 1).
  static Result<std::unique_ptr<ServoControl>> create(const ServoControlParams& p,
                                                      std::unique_ptr<control::Feedforward> feedforward);

  bool closed_loop() const { return closed_loop_; }
  int preview_samples() const { return ff_->preview_samples(); }
  const char* feedforward_name() const { return ff_->name(); }
  // RT-safe. After command(): the joint positions its command aims at when the feedforward
  // changed the reference (a smoothed velocity jump), and true; false: the plan's.
  bool feedforward_target(control::JointArray& r_mm) const { return ff_->target(r_mm); }
  // RT-safe. After command(): the share of its command a modelled load takes up (friction, weight).
  bool feedforward_load(control::JointArray& mm) const { return ff_->load_offset(mm); }

  // At rest at `at` (motion starts from rest): the feedforward's history. The PI state is kept
  // across stops (its correction is part of where the motor is); reset_all() clears it too.
  void reset_feedforward(const control::FeedforwardInput& at);
  void reset_all(const control::FeedforwardInput& at);

  // The loop runs on time-stamped encoder samples (issue 13, control.loop: host): the PI's
  // integral, the clamp on its output, the lost-step model, its baseline and the recovery all
  // advance by the time between a joint's samples, not by a count of servo cycles, so a late
  // cycle (one sample after 20 ms) neither doubles nor drops a correction; the encoder guard
  // judges a jump on the same timestamps.

  // One command sample the motors executed, for the lost-step model (motor command and expected
  // lead less the modelled loads' share).
  struct ExecutedSample {
    control::JointArray desired_mm{};
    control::JointArray motor_mm{};
    control::JointArray expected_lead_mm{};
  };
  // RT-safe. Once per servo period of executed time since the previous call, oldest first (a
  // hold of the plan repeats its held sample): advances the carriage model of each joint.
  void advance_model(const ExecutedSample& s);

  struct FeedbackInput {
    double now_s = 0.0;                    // this cycle's time (the servo clock)
    double print_time_s = 0.0;             // for events
    control::JointArray desired_mm{};      // r at the samples' time (the last advance_model()'s)
    control::JointArray encoder_mm{};      // joint coordinates; NaN: none
    control::JointArray sample_time_s{};   // when each was sampled (the servo clock; NaN: unknown)
    std::array<bool, 4> fresh{};           // a new sample arrived this cycle
  };
  // Once per servo cycle while motion runs, after advance_model() and before command(). Returns
  // false with a message in fault_text() when motion must stop (encoder fault or following
  // error); events (lost steps) are written to `event` when `*has_event`.
  bool update_feedback(const FeedbackInput& in, ServoEvent* event, bool* has_event);

  // One command sample: the reference P samples ahead in, the motor command out (u_ff + u_c).
  // The correction in the commands follows the PI's output at most at the rate the PI's clamp and
  // the recovery allow per command period, so the burst of samples after a late cycle ramps to a
  // correction that its longer dt allowed to move further, instead of jumping.
  void command(const control::FeedforwardInput& ahead, control::JointArray& u_ff_mm, control::JointArray& u_mm);

  const char* fault_text() const { return fault_text_; }
  const control::JointArray& correction_mm() const { return correction_mm_; }          // the PI's output
  const control::JointArray& commanded_correction_mm() const { return commanded_mm_; }  // in the last command

 private:
  ServoControl(const ServoControlParams& p, std::unique_ptr<control::Feedforward> ff);
  ServoControlParams p_;
  bool closed_loop_ = false;
  std::unique_ptr<control::Feedforward> ff_;
  std::array<control::PiController, 4> pi_;
  bool ff_inverts_ = false;  // the feedforward is a model inverse (lost-step prediction, above)
  std::array<control::LostStepDetector, 4> lost_;
  std::array<control::EncoderGuard, 4> guard_;
  control::JointArray correction_mm_{};
  control::JointArray commanded_mm_{};   // the correction in the last command sample
  double command_step_mm_ = 0.0;        // its largest change per command period
  std::array<model::DiscreteLtiFilter, 4> carriage_;  // configured where has_model_
  std::array<bool, 4> has_model_{};
  std::array<bool, 4> model_primed_{};
  std::array<bool, 4> base_primed_{};
  ExecutedSample last_executed_{};
  control::JointArray y_hat_mm_{};       // the model's carriage at the last executed sample
  std::array<bool, 4> have_y_hat_{};
  control::JointArray residual_base_mm_{};
  // A lag the model lacks (an encoder delay nobody declared), learned from the residual against
  // the plan's speed (drivers/device/lag_learner.hpp, as the device loop's slip check does).
  std::array<device::LagLearner, 4> lag_{};
  control::JointArray last_desired_mm_{};   // the plan at each joint's last accepted sample
  control::JointArray recovery_left_mm_{};  // slips still to be made up
  control::JointArray last_sample_s_{};     // time of each joint's last accepted sample
  std::array<bool, 4> have_sample_{};
  char fault_text_[160] = {};
};

// The control law the config asks for; nullptr when it asks for none (open loop, F = 1: the
// executor's exact path). Errors name the config section.
Result<std::unique_ptr<ServoControl>> make_servo_control(const config::MachineConfig& cfg);

}  // namespace feedloop::engine
