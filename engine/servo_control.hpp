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
#include "engine/telemetry_tap.hpp"
#include "model/discrete.hpp"

namespace feedloop::engine {

struct ServoControlParams {
  config::ControlConfig control;
  double period_s = 1e-3;
  std::array<bool, 4> has_encoder{};        // joints with an encoder (PI and guards act on these)
  std::array<double, 4> mm_per_full_step{};  // slips come in multiples of 4 full steps (0: unknown)
  std::array<std::string, 4> joint_names{};  // for the messages
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

  // Once per servo cycle while motion runs, before command(): the encoder readings (joint
  // coordinates; NaN: none), the desired positions at the time they were measured, the motor
  // command at that time and what the model expects the motor to lead the carriage by then.
  // Returns false with a message in fault_text() when motion must stop (encoder fault or
  // following error); events (lost steps) are written to `event` when `*has_event`.
  bool update_feedback(double print_time_s, const control::JointArray& desired_mm,
                       const control::JointArray& encoder_mm, const control::JointArray& motor_mm,
                       const control::JointArray& expected_lead_mm, const std::array<bool, 4>& fresh,
                       ServoEvent* event, bool* has_event);

  // One command sample: the reference P samples ahead in, the motor command out (u_ff + u_c).
  void command(const control::FeedforwardInput& ahead, control::JointArray& u_ff_mm, control::JointArray& u_mm);

  const char* fault_text() const { return fault_text_; }
  const control::JointArray& correction_mm() const { return correction_mm_; }

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
  std::array<model::DiscreteLtiFilter, 4> carriage_;  // configured where has_model_
  std::array<bool, 4> has_model_{};
  std::array<bool, 4> model_primed_{};
  control::JointArray residual_base_mm_{};
  control::JointArray recovery_left_mm_{};  // slips still to be made up
  char fault_text_[160] = {};
};

// The control law the config asks for; nullptr when it asks for none (open loop, F = 1: the
// executor's exact path). Errors name the config section.
Result<std::unique_ptr<ServoControl>> make_servo_control(const config::MachineConfig& cfg);

}  // namespace feedloop::engine
