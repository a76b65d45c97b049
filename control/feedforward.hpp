// The feedforward path F of the servo loop (closed-loop-gantry-thesis Sect. 4.6, Fig. 6): it maps
// the planned joint trajectory r (desired carriage positions) to the motor commands u_ff whose
// predicted carriage motion follows r. F = 1 is the thesis's open loop; the input shapers
// (control/input_shaper.hpp) and the model inverses (control/feedforward/) are the others.
//
// Contract (servo thread, once per period T): step() at cycle k receives the reference at
// t_{k+P}, P = preview_samples(), and returns the motor command for t_k. A filter that needs no
// preview has P = 0. The servo samples the plan P periods ahead, so a stable approximate inverse
// of a non-minimum-phase model (delta paper Eq. 34, d1 < 0) can look into the future.
// step() and reset() are RT-safe: no allocation, no locks, bounded time.
#pragma once

#include <array>
#include <memory>

#include "planner/joint_output.hpp"

namespace feedloop::control {

inline constexpr int kJoints = planner::kJoints;  // 3 motors + extruder
using JointArray = std::array<double, kJoints>;

struct FeedforwardInput {
  JointArray r_mm{};             // desired joint (carriage) positions at t_{k+P}
  std::array<double, 3> nozzle_mm{};  // planned nozzle position at t_{k+P} (LPV scheduling)
};

class Feedforward {
 public:
  virtual ~Feedforward() = default;
  virtual const char* name() const = 0;
  // Periods of preview the filter needs (>= 0).
  virtual int preview_samples() const = 0;
  // RT-safe. At rest at `at`: every internal state as if `at` had been held forever.
  virtual void reset(const FeedforwardInput& at) = 0;
  // RT-safe. One period: the reference at t_{k+P} in, the motor command for t_k out.
  virtual void step(const FeedforwardInput& in, JointArray& u_mm) = 0;
  // RT-safe. The steps and the encoders were referenced to each other at `at` (the machine's
  // start, a homing, a resync after a fault): a model whose motor travel differs from the
  // carriage's by a factor (the identified scale_error) counts that travel from here.
  virtual void rereference(const FeedforwardInput& /*at*/) {}
  // RT-safe. When the filter changes the reference it follows (velocity_jump_smoother.hpp): the
  // joint positions at t_k that the last step()'s command aims at, and true. false: the plan's.
  virtual bool target(JointArray& /*r_mm*/) const { return false; }
  // RT-safe. The part of the last step()'s command that a modelled load (friction, the effector's
  // weight) takes up as stretch of motor and belt, not as motion, and true; false: none. The lost-
  // step detector's linear model (which has no such load) is driven by the command without it.
  virtual bool load_offset(JointArray& /*mm*/) const { return false; }
  // Whether the command is a model inverse's (the carriage is predicted to follow target(), or the
  // reference): the lost-step detector then predicts the carriage as that reference plus its own
  // model's response to the correction only, instead of running its simpler model on all of u.
  virtual bool inverts_model() const { return false; }
};

// F = 1: the motor command is the desired position (no preview).
class IdentityFeedforward final : public Feedforward {
 public:
  const char* name() const override { return "none"; }
  int preview_samples() const override { return 0; }
  void reset(const FeedforwardInput&) override {}
  void step(const FeedforwardInput& in, JointArray& u_mm) override { u_mm = in.r_mm; }
};

}  // namespace feedloop::control
