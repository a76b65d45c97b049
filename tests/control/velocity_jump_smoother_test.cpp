// The velocity-jump smoother (control/feedforward/velocity_jump_smoother.hpp) in front of F = 1:
// what it leaves alone (constant velocity, accelerations below the limit) and what it does to a
// corner whose velocity jumps (the thesis's speed-change rule at 300 mm/s).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "control/feedforward/velocity_jump_smoother.hpp"
#include "feedforward_test_support.hpp"

namespace feedloop::control {
namespace {

constexpr double kT = 1e-3;

std::unique_ptr<VelocityJumpSmoother> make(double a_max = 10000.0, int h_max = 15) {
  VelocityJumpSmoothing p;
  p.period_s = kT;
  p.max_accel_mm_s2 = a_max;
  p.max_half_width = h_max;
  auto s = VelocityJumpSmoother::create(std::make_unique<IdentityFeedforward>(), p);
  EXPECT_TRUE(s.ok());
  return std::move(s.value());
}

// Runs the smoother over x(k), y(k) (k = 0 .. n-1) and returns its commands for t_k, with the
// target() it reports for each.
struct Out {
  std::vector<double> ux, uy, tx, ty;
};
template <class F>
Out run(VelocityJumpSmoother& s, F ref, int n) {
  const int P = s.preview_samples();
  FeedforwardInput at;
  ref(0, at.r_mm);
  s.reset(at);
  Out o;
  for (int k = 0; k < n; ++k) {
    FeedforwardInput in;
    ref(k + P, in.r_mm);
    JointArray u{}, t{};
    s.step(in, u);
    EXPECT_TRUE(s.target(t));
    o.ux.push_back(u[0]);
    o.uy.push_back(u[1]);
    o.tx.push_back(t[0]);
    o.ty.push_back(t[1]);
  }
  return o;
}

TEST(VelocityJumpSmoother, LeavesFeasibleReferencesAlone) {
  auto s = make();
  EXPECT_EQ(s->preview_samples(), 31);  // F = 1 has none; the window 2 h_max + 1
  // Trapezoids at 3000 and 6000 mm/s^2 (the planner's): nothing above 10000 mm/s^2.
  const fftest::Trapezoid mx{0.0, 30.0, 100.0, 3000.0, 0.05}, my{5.0, -10.0, 150.0, 6000.0, 0.1};
  auto ref = [&](int k, JointArray& r) { r = {mx.at(k * kT), my.at(k * kT), 1.0, 0.1 * k}; };
  const Out o = run(*s, ref, 400);
  for (int k = 0; k < 400; ++k) {
    JointArray r{};
    ref(k, r);
    ASSERT_NEAR(o.ux[static_cast<size_t>(k)], r[0], 1e-12) << k;
    ASSERT_NEAR(o.uy[static_cast<size_t>(k)], r[1], 1e-12) << k;
    ASSERT_NEAR(o.tx[static_cast<size_t>(k)], r[0], 1e-12) << k;
  }
  EXPECT_EQ(s->jumps(), 0);
}

TEST(VelocityJumpSmoother, SpreadsAVelocityJumpAtTheLimitAndCutsTheCornerSymmetrically) {
  // A 150 mm/s corner turning 142 degrees (the large star's tip) with no slowdown: |Delta v| =
  // 2 v sin(71 deg) = 284 mm/s in one period.
  // From rest at 3000 mm/s^2 (from k = 50), cruising well before the corner at k = 200.
  const double v = 150.0, a = 3000.0, turn = 142.0 * M_PI / 180.0;
  const int corner = 200;
  auto path_mm = [&](int k) {
    const double t = (k - 50) * kT, ta = v / a;
    return t <= 0 ? 0.0 : t < ta ? 0.5 * a * t * t : 0.5 * a * ta * ta + v * (t - ta);
  };
  auto ref = [&](int k, JointArray& r) {
    const double s = path_mm(k), sc = path_mm(corner);
    if (k <= corner)
      r = {s, 0.0, 0.0, 0.0};
    else
      r = {sc + (s - sc) * std::cos(turn), (s - sc) * std::sin(turn), 0.0, 0.0};
  };
  auto s = make(10000.0, 15);
  const Out o = run(*s, ref, 400);
  EXPECT_EQ(s->jumps(), 1);
  double max_a = 0.0, max_dev = 0.0;
  int first = -1, last = -1;
  for (int k = 1; k + 1 < 400; ++k) {
    const size_t i = static_cast<size_t>(k);
    const double ax = (o.ux[i + 1] - 2 * o.ux[i] + o.ux[i - 1]) / (kT * kT);
    const double ay = (o.uy[i + 1] - 2 * o.uy[i] + o.uy[i - 1]) / (kT * kT);
    max_a = std::max(max_a, std::hypot(ax, ay));
    JointArray r{};
    ref(k, r);
    const double dev = std::hypot(o.ux[i] - r[0], o.uy[i] - r[1]);
    if (dev > 1e-12) {
      if (first < 0) first = k;
      last = k;
    }
    max_dev = std::max(max_dev, dev);
    // target() is what the command aims at: here (F = 1) the command itself.
    EXPECT_DOUBLE_EQ(o.tx[i], o.ux[i]);
  }
  std::printf("corner: max acceleration %.0f mm/s^2, max deviation %.3f mm over samples %d..%d\n",
              max_a, max_dev, first, last);
  // 284 mm/s over 2 h + 1 = 29 periods: 9.8 m/s^2 in the box, a little more where the blend
  // ramps in; before: 284 m/s^2.
  EXPECT_LT(max_a, 1.5 * 10000.0);
  EXPECT_GT(max_a, 0.5 * 10000.0);
  // Only around the corner, and symmetric about it (the box mean is a symmetric corner cut).
  EXPECT_EQ(corner - first, last - corner);
  EXPECT_LE(last - corner, 2 * 15);
  // The cut: at most the corner's half-window chord error, v h T / 2 = 1.05 mm at h = 14.
  EXPECT_LT(max_dev, 1.1);
  EXPECT_GT(max_dev, 0.2);
}

TEST(VelocityJumpSmoother, RejectsBadParameters) {
  VelocityJumpSmoothing p;
  EXPECT_FALSE(VelocityJumpSmoother::create(nullptr, p).ok());
  p.max_accel_mm_s2 = 0.0;
  EXPECT_FALSE(VelocityJumpSmoother::create(std::make_unique<IdentityFeedforward>(), p).ok());
  p = VelocityJumpSmoothing{};
  p.max_half_width = 0;
  EXPECT_FALSE(VelocityJumpSmoother::create(std::make_unique<IdentityFeedforward>(), p).ok());
}

}  // namespace
}  // namespace feedloop::control
