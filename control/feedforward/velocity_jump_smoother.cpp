// Velocity-jump smoothing of the reference ahead of a model inverse (see
// velocity_jump_smoother.hpp).
#include "control/feedforward/velocity_jump_smoother.hpp"

#include <algorithm>  // std::clamp, std::max
#include <cmath>      // std::abs, std::ceil, std::isfinite

namespace feedloop::control {

namespace {
constexpr int kMotionJoints = 3;  // the extruder (joint 3) passes through
}

Result<std::unique_ptr<VelocityJumpSmoother>> VelocityJumpSmoother::create(
    std::unique_ptr<Feedforward> inner, const VelocityJumpSmoothing& params) {
  if (!inner) return Error{"velocity-jump smoothing: no feedforward to feed", {}};
  if (!(params.period_s > 0.0 && std::isfinite(params.period_s)))
    return Error{"velocity-jump smoothing: the servo period must be > 0", {}};
  if (!(params.max_accel_mm_s2 > 0.0 && std::isfinite(params.max_accel_mm_s2)))
    return Error{"velocity-jump smoothing: max_accel_mm_s2 must be > 0 and finite", {}};
  if (params.max_half_width < 1)
    return Error{"velocity-jump smoothing: the window must span at least 3 periods", {}};
  std::unique_ptr<VelocityJumpSmoother> s(new VelocityJumpSmoother());
  s->p_ = params;
  s->h_max_ = params.max_half_width;
  s->extra_ = 2 * s->h_max_ + 1;
  s->ring_.assign(static_cast<size_t>(4 * s->h_max_ + 3), FeedforwardInput{});
  s->smoothed_.assign(static_cast<size_t>(inner->preview_samples() + 1), JointArray{});
  s->inner_ = std::move(inner);
  return s;
}

const FeedforwardInput& VelocityJumpSmoother::at_(int offset) const {
  const int n = static_cast<int>(ring_.size());
  const int back = extra_ - offset;  // the newest sample is at offset 2 h_max + 1
  return ring_[static_cast<size_t>(((head_ - back) % n + n) % n)];
}

void VelocityJumpSmoother::reset(const FeedforwardInput& at) {
  for (FeedforwardInput& r : ring_) r = at;
  for (JointArray& r : smoothed_) r = at.r_mm;
  head_ = 0;
  smoothed_head_ = 0;
  inner_->reset(at);
}

void VelocityJumpSmoother::step(const FeedforwardInput& in, JointArray& u_mm) {
  const int n = static_cast<int>(ring_.size());
  head_ = (head_ + 1) % n;
  ring_[static_cast<size_t>(head_)] = in;
  // a_max as a second difference (mm per period^2).
  const double limit_mm = p_.max_accel_mm_s2 * p_.period_s * p_.period_s;
  int h = 0;
  double alpha = 0.0;
  for (int d = -2 * h_max_; d <= 2 * h_max_; ++d) {
    double a_mm = 0.0;
    const FeedforwardInput &prev = at_(d - 1), &here = at_(d), &next = at_(d + 1);
    for (size_t j = 0; j < kMotionJoints; ++j)
      a_mm = std::max(a_mm, std::abs(next.r_mm[j] - 2.0 * here.r_mm[j] + prev.r_mm[j]));
    if (!(a_mm > limit_mm)) continue;
    // 2 h_j + 1 >= Delta v / (a_max T) = a_mm / limit_mm.
    const int hj =
        std::clamp(static_cast<int>(std::ceil(0.5 * (a_mm / limit_mm - 1.0))), 1, h_max_);
    const int dist = std::abs(d);
    if (dist > 2 * hj) continue;
    alpha = std::max(alpha, std::clamp(2.0 - static_cast<double>(dist) / hj, 0.0, 1.0));
    h = std::max(h, hj);
    if (d == 0) ++jumps_;  // counted once, as it passes the centre
  }
  FeedforwardInput c = at_(0);
  if (alpha > 0.0) {
    for (size_t j = 0; j < kMotionJoints; ++j) {
      double sum = 0.0;
      for (int d = -h; d <= h; ++d) sum += at_(d).r_mm[j];
      c.r_mm[j] += alpha * (sum / (2 * h + 1) - c.r_mm[j]);
    }
  }
  const int m = static_cast<int>(smoothed_.size());
  smoothed_head_ = (smoothed_head_ + 1) % m;
  smoothed_[static_cast<size_t>(smoothed_head_)] = c.r_mm;
  inner_->step(c, u_mm);
}

bool VelocityJumpSmoother::target(JointArray& r_mm) const {
  // The oldest of the last P_inner + 1 centres: r_s at t_k.
  const int m = static_cast<int>(smoothed_.size());
  r_mm = smoothed_[static_cast<size_t>((smoothed_head_ + 1) % m)];
  return true;
}

}  // namespace feedloop::control
