// The servo thread's control law (see servo_control.hpp).
#include "engine/servo_control.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "control/input_shaper.hpp"
#include "engine/config_mapping.hpp"
#include "engine/control_config.hpp"
#include "model/gantry_axis.hpp"
#include "planner/kinematics.hpp"

namespace feedloop::engine {

Result<std::unique_ptr<ServoControl>> ServoControl::create(const ServoControlParams& p,
                                                           std::unique_ptr<control::Feedforward> feedforward) {
  if (!feedforward) feedforward = std::make_unique<control::IdentityFeedforward>();
  std::unique_ptr<ServoControl> c(new ServoControl(p, std::move(feedforward)));
  const char* names[4] = {"j0", "j1", "j2", "j3"};
  for (size_t j = 0; j < 4; ++j) {
    const std::string axis = p.joint_names[j].empty() ? names[j] : p.joint_names[j];
    if (Status s = c->pi_[j].configure(pi_params_from_config(p.control, axis, p.period_s)); !s)
      return Error{"control: " + axis + ": " + s.error().message};
    control::LostStepParams lp = lost_step_params_from_config(p.control, p.mm_per_full_step[j]);
    lp.period_s = p.period_s;
    // A slip is permanent, a transient of the model residual (a resonance the model has slightly
    // off) is not: the residual must stay beyond the threshold for lost_step_confirm_s.
    lp.settle_periods = std::max(lp.settle_periods, static_cast<int>(std::lround(p.lost_step_confirm_s / p.period_s)));
    if (Status s = c->lost_[j].configure(lp); !s)
      return Error{std::string("control: ") + s.error().message};
    control::EncoderGuardParams gp = p.guard[j];
    gp.axis = axis;
    if (Status s = c->guard_[j].configure(gp); !s) return Error{std::string("control: ") + s.error().message};
    if (p.carriage_model[j]) {
      auto d = model::discretize_zoh(*p.carriage_model[j], p.period_s);
      if (!d.ok()) return Error{"control: carriage model of " + axis + ": " + d.error().message};
      if (Status s = c->carriage_[j].configure(d.value()); !s)
        return Error{"control: carriage model of " + axis + ": " + s.error().message};
      c->has_model_[j] = true;
    }
  }
  return c;
}

ServoControl::ServoControl(const ServoControlParams& p, std::unique_ptr<control::Feedforward> ff)
    : p_(p),
      closed_loop_(p.control.mode == config::ControlMode::pi && p.control.loop == config::ControlLoop::host),
      ff_(std::move(ff)) {
  ff_inverts_ = ff_->inverts_model();
  command_step_mm_ = (p.control.max_correction_mm_s + p.recovery_mm_s) * p.period_s;
}

// Motion restarts from rest: the loop was open meanwhile, so the next samples' intervals start
// there (not at the last sample of the previous motion).
void ServoControl::reset_feedforward(const control::FeedforwardInput& at) {
  ff_->reset(at);
  for (size_t j = 0; j < 4; ++j) guard_[j].restart();
  have_sample_.fill(false);
}

void ServoControl::reset_all(const control::FeedforwardInput& at) {
  ff_->rereference(at);
  ff_->reset(at);
  for (size_t j = 0; j < 4; ++j) {
    pi_[j].reset();
    lost_[j].reset();
    lag_[j].reset();
    guard_[j].reset();
  }
  correction_mm_.fill(0.0);
  commanded_mm_.fill(0.0);
  model_primed_.fill(false);
  base_primed_.fill(false);
  have_y_hat_.fill(false);
  have_sample_.fill(false);
  residual_base_mm_.fill(0.0);
  recovery_left_mm_.fill(0.0);
  fault_text_[0] = '\0';
}

// Lost steps: where the model puts the carriage for the motor commands executed (y_hat) against
// the encoder. The model is a ZOH discretisation at the servo period, so it advances once per
// period of executed time whatever the host's cycles did meanwhile.
void ServoControl::advance_model(const ExecutedSample& x) {
  last_executed_ = x;
  for (size_t j = 0; j < 4; ++j) {
    if (!p_.has_encoder[j]) continue;
    if (!has_model_[j]) {
      y_hat_mm_[j] = x.motor_mm[j] - x.expected_lead_mm[j];
      have_y_hat_[j] = true;
      continue;
    }
    // Behind a model inverse (a better model than this one: position- and direction-dependent
    // belt, friction) the carriage is predicted at the desired position plus this model's
    // response to the correction u - u_ff alone; otherwise this model runs on all of u.
    const double correction_mm = x.motor_mm[j] - x.expected_lead_mm[j] - x.desired_mm[j];
    const double u_m = (ff_inverts_ ? correction_mm : x.motor_mm[j]) * 1e-3;
    if (!model_primed_[j]) {
      carriage_[j].reset_to_steady_state(&u_m);
      model_primed_[j] = true;
    }
    double y_m = 0.0;
    carriage_[j].step(&u_m, &y_m);
    y_hat_mm_[j] = (ff_inverts_ ? x.desired_mm[j] : 0.0) + y_m * 1e3;
    have_y_hat_[j] = true;
  }
}

bool ServoControl::update_feedback(const FeedbackInput& in, ServoEvent* event, bool* has_event) {
  *has_event = false;
  for (size_t j = 0; j < 4; ++j) {
    if (!p_.has_encoder[j]) continue;
    control::EncoderGuardInput g;
    g.fresh = in.fresh[j];
    g.encoder_mm = in.encoder_mm[j];
    g.sample_time_s = in.sample_time_s[j];
    g.now_s = in.now_s;
    g.reference_mm = in.desired_mm[j];
    if (guard_[j].update(g) != control::EncoderFault::none) {
      std::snprintf(fault_text_, sizeof fault_text_, "%s", guard_[j].message());
      event->kind = guard_[j].fault() == control::EncoderFault::following_error ? ServoEventKind::kFollowingError
                                                                                : ServoEventKind::kEncoderFault;
      event->print_time_s = in.print_time_s;
      event->joint = static_cast<int>(j);
      event->size_mm = in.desired_mm[j] - in.encoder_mm[j];
      return false;
    }
    // No new sample, or one the guard rejected: nothing new to act on; the time until the next
    // accepted sample goes into that one's dt.
    if (!guard_[j].sample_accepted() || !have_y_hat_[j]) continue;
    const double t_s = std::isfinite(in.sample_time_s[j]) ? in.sample_time_s[j] : in.now_s;
    const bool had_sample = have_sample_[j];
    double dt_s = had_sample ? t_s - last_sample_s_[j] : p_.period_s;
    if (!(dt_s > 0.0)) dt_s = p_.period_s;  // a repeated or reordered timestamp: one period
    last_sample_s_[j] = t_s;
    have_sample_[j] = true;
    // The plan's speed since the last accepted sample (0 at a motion's first).
    const double v_mm_s = had_sample ? (in.desired_mm[j] - last_desired_mm_[j]) / dt_s : 0.0;
    last_desired_mm_[j] = in.desired_mm[j];

    const double encoder_mm = in.encoder_mm[j];
    if (!base_primed_[j]) {
      residual_base_mm_[j] = last_executed_.motor_mm[j] - encoder_mm;
      base_primed_[j] = true;
    }
    // Slow drifts of the residual (a steps/mm error the PI is correcting, thermal growth) are
    // tracked by a baseline and are not slips; a slip is a sudden jump of a whole torque cycle of
    // the stepper (4 full steps: the rotor sits in the next equilibrium of the field). Recovery:
    // the motor command moves on by the slip, at recovery_mm_s (a jump of a whole cycle would be
    // invisible to the rotor, the torque law being periodic), so the rotor is carried the missing
    // steps back onto the path; the detector's sum of slips S accounts for the model's y_hat
    // running ahead of the carriage by what was lost.
    const double residual_mm = y_hat_mm_[j] - encoder_mm;
    // A lag the model lacks reads as tau v (an encoder delay); learned on the residual net of its
    // baseline and of the slips where what is left is under the slip threshold, and taken off
    // (lag_learner.hpp).
    lag_[j].learn(static_cast<float>(residual_mm - lost_[j].total_mm() - residual_base_mm_[j]),
                  static_cast<float>(v_mm_s), static_cast<float>(dt_s),
                  static_cast<float>(lost_[j].params().threshold_mm));
    const double lag_mm = static_cast<double>(lag_[j].lag_s()) * v_mm_s;
    // The baseline follows the residual net of the slips already reported (the detector
    // subtracts their sum S itself): a first-order filter with time constant residual_baseline_s.
    if (!lost_[j].pending())
      residual_base_mm_[j] += (residual_mm - lag_mm - lost_[j].total_mm() - residual_base_mm_[j]) *
                              std::min(1.0, dt_s / p_.residual_baseline_s);
    if (auto slip = lost_[j].update(residual_mm - lag_mm - residual_base_mm_[j], 0.0, 0.0, dt_s)) {
      lag_[j].pause(device::kLagQuietAfterSlipS);  // the recovery's motion is no lag
      recovery_left_mm_[j] += slip->size_mm;
      event->kind = ServoEventKind::kLostSteps;
      event->print_time_s = in.print_time_s;
      event->joint = static_cast<int>(j);
      event->size_mm = slip->size_mm;
      *has_event = true;
    }
    if (recovery_left_mm_[j] != 0.0) {  // carry the rotor back, at recovery_mm_s
      const double max_mm = p_.recovery_mm_s * dt_s;
      const double step_mm = std::clamp(recovery_left_mm_[j], -max_mm, max_mm);
      pi_[j].shift(step_mm);
      recovery_left_mm_[j] -= step_mm;
    }
    // Thesis Sect. 4.6: I[k] = I[k-1] + K_I e[k] (t[k] - t[k-1]), the clamp over the same dt.
    correction_mm_[j] = pi_[j].update(in.desired_mm[j] - encoder_mm, dt_s);
  }
  return true;
}

void ServoControl::command(const control::FeedforwardInput& ahead, control::JointArray& u_ff_mm,
                           control::JointArray& u_mm) {
  ff_->step(ahead, u_ff_mm);
  for (size_t j = 0; j < 4; ++j) {
    if (closed_loop_)
      commanded_mm_[j] += std::clamp(correction_mm_[j] - commanded_mm_[j], -command_step_mm_, command_step_mm_);
    u_mm[j] = u_ff_mm[j] + (closed_loop_ ? commanded_mm_[j] : 0.0);
  }
}

// ---- from the config -----------------------------------------------------------------------------

Result<std::unique_ptr<ServoControl>> make_servo_control(const config::MachineConfig& cfg) {
  const bool closed = cfg.control.mode == config::ControlMode::pi;
  if (!closed && cfg.feedforward.type == config::FeedforwardType::none) return std::unique_ptr<ServoControl>();
  const double period_s = 1.0 / cfg.servo.rate_hz;
  ServoControlParams p;
  p.control = cfg.control;
  p.period_s = period_s;
  const auto names = joint_names(cfg);
  for (size_t j = 0; j < 4; ++j) {
    p.joint_names[j] = names[j];
    const config::AxisConfig* a = cfg.axis(names[j]);
    p.has_encoder[j] = closed && a != nullptr && a->encoder.has_value();
    p.guard[j] = encoder_guard_params_from_config(cfg, names[j]);
    // A stepper's torque law repeats every 4 full steps: 2 pi r / n_r per cycle (thesis Eq. 2).
    if (const config::GantryModelConfig* g = cfg.model.gantry_for(names[j]);
        g != nullptr && cfg.kinematics != config::Kinematics::delta) {
      p.mm_per_full_step[j] = g->stepper.full_step_mm();
      p.carriage_model[j] = model::gantry_state_space(gantry_params_from_config(*g));
    }
  }
  std::unique_ptr<control::Feedforward> ff;
  switch (cfg.feedforward.type) {
    case config::FeedforwardType::none: break;
    case config::FeedforwardType::shaper: {
      const auto kin = planner::make_kinematics(planner_config(cfg));
      auto setup = input_shaper_setup(cfg.feedforward.shaper, *kin, period_s);
      if (!setup.ok()) return Error{"feedforward.shaper: " + setup.error().message};
      auto shaper = std::make_unique<control::InputShaper>();
      if (Status s = shaper->configure(setup.value()); !s) return Error{"feedforward.shaper: " + s.error().message};
      ff = std::move(shaper);
      break;
    }
    case config::FeedforwardType::lpv: {
      auto m = make_model_feedforward(cfg, period_s, cfg.feedforward.lpv.freeze_at_centre);
      if (!m.ok()) return Error{"feedforward.lpv: " + m.error().message};
      ff = std::move(m.value());
      break;
    }
  }
  return ServoControl::create(p, std::move(ff));
}

}  // namespace feedloop::engine
