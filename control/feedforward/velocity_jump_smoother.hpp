// Velocity jumps in the reference, made feasible before a model inverse sees them.
//
// A corner rule that lets the velocity jump (the thesis's speed change, closed-loop-gantry-thesis
// Sect. 2.2; Marlin's "jerk") hands the servo a reference whose acceleration is Delta v / T in
// the period of the corner: 284 mm/s on the large star at 300 mm/s, 284 m/s^2 at 1 kHz, or
// 340 N on the 1.2 kg Y axis. A model inverse follows such a reference on paper and demands that
// force of a stepper whose pull-out is tens of N: the motor slips and the steps are lost. This
// filter spreads each jump over the time it needs at a feasible acceleration a_max and leaves
// the reference alone elsewhere:
//
//   r_s(c) = r(c) + alpha(c) (MA_h(r)(c) - r(c)),   MA_h: the mean of the 2h + 1 samples around c
//
// A sample j is a jump when the reference's second difference there exceeds a_max:
// |r(j+1) - 2 r(j) + r(j-1)| / T^2 > a_max, with Delta v_j = |...| / T. The box that turns it into
// a ramp at a_max is 2 h_j + 1 >= Delta v_j / (a_max T) samples wide (h_j capped by the preview
// budget h_max). Around a jump alpha = 1 within h_j samples and falls linearly to 0 at 2 h_j (so
// the blend is continuous); h(c) and alpha(c) are the largest over the jumps within reach and over
// the motion joints (one window for all joints keeps the path's shape: the box mean of a corner is
// the symmetric corner cut, and on a straight line at constant velocity MA_h(r) = r). The
// extruder joint passes through, delayed like the rest.
//
// A Feedforward decorator: the inner filter gets r_s at t_{c}, c = k + P_inner, and the preview
// grows by 2 h_max + 1. target() gives r_s at t_k, what the command for t_k aims at: the servo's
// PI compares the encoders with it (not with r), or it would undo the smoothing and slip the motor.
// RT-safe step() and reset(): fixed-size rings sized at create().
#pragma once

#include <memory>
#include <vector>

#include "control/feedforward.hpp"
#include "core/result.hpp"

namespace feedloop::control {

struct VelocityJumpSmoothing {
  double period_s = 1e-3;            // servo period T
  double max_accel_mm_s2 = 20000.0;  // a_max per joint: a reference beyond it is a velocity jump
  int max_half_width = 10;           // h_max, samples (the box spans at most 2 h_max + 1 periods)
};

class VelocityJumpSmoother final : public Feedforward {
 public:
  // Errors: a null inner filter, T or a_max not > 0 and finite, h_max < 1.
  static Result<std::unique_ptr<VelocityJumpSmoother>> create(std::unique_ptr<Feedforward> inner,
                                                              const VelocityJumpSmoothing& params);

  const char* name() const override { return inner_->name(); }
  int preview_samples() const override { return inner_->preview_samples() + extra_; }
  void reset(const FeedforwardInput& at) override;
  void step(const FeedforwardInput& in, JointArray& u_mm) override;
  bool target(JointArray& r_mm) const override;
  bool load_offset(JointArray& mm) const override { return inner_->load_offset(mm); }
  void rereference(const FeedforwardInput& at) override { inner_->rereference(at); }
  bool inverts_model() const override { return inner_->inverts_model(); }

  // Jumps seen so far (samples where the reference's acceleration exceeded a_max); for tests.
  long jumps() const { return jumps_; }

 private:
  VelocityJumpSmoother() = default;
  const FeedforwardInput& at_(
      int offset) const;  // the sample offset from the centre (-2h-1 .. 2h+1)

  std::unique_ptr<Feedforward> inner_;
  VelocityJumpSmoothing p_;
  int h_max_ = 10;
  int extra_ = 21;  // 2 h_max + 1 more preview
  std::vector<FeedforwardInput>
      ring_;                          // the last 4 h_max + 3 inputs; newest = centre + 2 h_max + 1
  int head_ = 0;                      // index of the newest
  std::vector<JointArray> smoothed_;  // r_s of the last P_inner + 1 centres; oldest = t_k
  int smoothed_head_ = 0;
  long jumps_ = 0;
};

}  // namespace feedloop::control
