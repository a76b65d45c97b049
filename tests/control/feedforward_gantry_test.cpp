// Gantry LPV feedforward (control/feedforward/gantry_lpv.hpp) on the linear thesis model itself
// (Eq. 15 with the position-dependent belt of Eq. 6), simulated 20x finer than the servo period:
// tracking vs u = r, vs a constant-stiffness model, the static gain, preview and pass-through.
#include <gtest/gtest.h>

#include <cstdio>

#include "control/feedforward/gantry_lpv.hpp"
#include "control/feedforward/model_feedforward.hpp"
#include "feedforward_test_support.hpp"

namespace feedloop::control {
namespace {

constexpr double kT = 1e-3;  // 1 kHz servo (thesis)

// The config example's X (extruder carriage) and Y (whole X gantry) axes (Tables 2-4, Eq. 6).
GantryAxisLpvModel axis_model(bool y_axis) {
  GantryAxisLpvModel m;
  m.params = y_axis ? model::thesis_y_axis() : model::thesis_x_axis();
  m.belt_unit_stiffness_n = m.params.k2_n_m * 0.3;  // k_hat = k2 L
  m.pulley_distance_mm = 300.0;
  m.min_mm = -150.0;
  m.max_mm = 150.0;
  return m;
}

std::unique_ptr<GantryLpvFeedforward> make(bool lpv, double rho = PreviewWeights{}.rho) {
  std::array<GantryAxisLpvModel, 2> axes{axis_model(false), axis_model(true)};
  if (!lpv)
    for (auto& a : axes) a.belt_unit_stiffness_n = 0.0;  // constant k2 (the value at x = 0)
  LpvDesignOptions opt;
  opt.period_s = kT;
  opt.preview_samples = 20;
  opt.weights.rho = rho;
  auto ff = GantryLpvFeedforward::create(axes, opt);
  EXPECT_TRUE(ff.ok()) << (ff.ok() ? "" : ff.error().message);
  return std::move(ff.value());
}

// The plant: both axes, each Eq. 15 with K2 at its current carriage position (LPV).
fftest::FineSim plant() {
  const GantryAxisLpvModel mx = axis_model(false), my = axis_model(true);
  return fftest::FineSim(
      [mx, my](const Eigen::VectorXd& y_mm) {
        model::StateSpace s;
        s.A = Eigen::MatrixXd::Zero(8, 8);
        s.B = Eigen::MatrixXd::Zero(8, 2);
        s.C = Eigen::MatrixXd::Zero(2, 8);
        s.D = Eigen::MatrixXd::Zero(2, 2);
        for (int a = 0; a < 2; ++a) {
          const GantryAxisLpvModel& m = a == 0 ? mx : my;
          model::GantryAxisParams p = m.params;
          p.k2_n_m = belt_stiffness_n_m(m, y_mm[a]);
          const model::StateSpace g = model::gantry_state_space(p);
          s.A.block(4 * a, 4 * a, 4, 4) = g.A;
          s.B.block(4 * a, a, 4, 1) = g.B;
          s.C.block(a, 4 * a, 1, 4) = g.C;
        }
        return s;
      },
      kT);
}

// X and Y moves at once: x from -100 to +100 mm, y from 100 to -60 mm (150 mm/s, 3000 mm/s^2).
FeedforwardInput plan_at(int k) {
  static const fftest::Trapezoid mx{-100.0, 100.0, 150.0, 3000.0, 0.05};
  static const fftest::Trapezoid my{100.0, -60.0, 150.0, 3000.0, 0.05};
  FeedforwardInput in;
  const double t = k * kT;
  in.r_mm = {mx.at(t), my.at(t), 5.0 + 0.01 * k, 0.1 * k};
  in.nozzle_mm = {in.r_mm[0], in.r_mm[1], in.r_mm[2]};
  return in;
}
constexpr int kSteps = 1600;  // 1.6 s: both moves end at ~1.48 s

TEST(GantryLpvFeedforward, TracksTheLinearModelTenTimesBetterThanUEqualsR) {
  auto ff = make(true);
  auto sim0 = plant(), sim1 = plant();
  const fftest::TrackingError open = fftest::run(nullptr, sim0, 2, kSteps, plan_at);
  const fftest::TrackingError lpv = fftest::run(ff.get(), sim1, 2, kSteps, plan_at);
  std::printf("gantry trapezoid: u=r max %.1f um rms %.1f um | LPV ff max %.3f um rms %.3f um (ratio max %.0f)\n",
              open.max_um, open.rms_um, lpv.max_um, lpv.rms_um, open.max_um / lpv.max_um);
  EXPECT_GT(open.max_um, 100.0);  // the lag of the open loop at 150 mm/s is real
  EXPECT_GT(open.max_um / lpv.max_um, 10.0);
  EXPECT_GT(open.rms_um / lpv.rms_um, 10.0);
  EXPECT_LT(lpv.final_u_minus_r_mm, 1e-6);  // settled back onto the reference
}

TEST(GantryLpvFeedforward, PositionDependentBeltBeatsConstantStiffness) {
  auto lpv = make(true), fixed = make(false);
  auto s0 = plant(), s1 = plant();
  const fftest::TrackingError e_lpv = fftest::run(lpv.get(), s0, 2, kSteps, plan_at);
  const fftest::TrackingError e_fix = fftest::run(fixed.get(), s1, 2, kSteps, plan_at);
  std::printf("gantry: LPV belt max %.3f um vs constant k2 max %.3f um\n", e_lpv.max_um, e_fix.max_um);
  EXPECT_LT(e_lpv.max_um * 3.0, e_fix.max_um);
}

TEST(GantryLpvFeedforward, StaticGainIsOneAndPassThroughIsDelayedByThePreview) {
  auto ff = make(true);
  FeedforwardInput at;
  at.r_mm = {12.5, -40.0, 3.0, 7.0};
  ff->reset(at);
  JointArray u{};
  const int P = ff->preview_samples();
  EXPECT_EQ(P, 20);
  for (int k = 0; k < 300; ++k) {
    FeedforwardInput in = at;
    in.r_mm[2] = 3.0 + k;  // z and e pass through, delayed by P
    in.r_mm[3] = 7.0 - k;
    ff->step(in, u);
    EXPECT_NEAR(u[0], 12.5, 1e-8);  // 10 pm: rounding only
    EXPECT_NEAR(u[1], -40.0, 1e-8);
    EXPECT_DOUBLE_EQ(u[2], k >= P ? 3.0 + (k - P) : 3.0);
    EXPECT_DOUBLE_EQ(u[3], k >= P ? 7.0 - (k - P) : 7.0);
  }
}

TEST(GantryLpvFeedforward, UsesThePreviewAndNoMore) {
  // A reference step of 1 mm on x at t_c = 100 periods: commands before t_c - P must not move,
  // the command must anticipate (move before t_c) and stay bounded.
  auto ff = make(true);
  const int P = ff->preview_samples(), c = 100;
  FeedforwardInput rest;
  ff->reset(rest);
  JointArray u{};
  double first_move = -1, max_dev = 0;
  for (int k = 0; k < 400; ++k) {
    FeedforwardInput in;
    in.r_mm[0] = (k + P >= c) ? 1.0 : 0.0;
    ff->step(in, u);
    if (first_move < 0 && std::abs(u[0]) > 1e-12) first_move = k;
    max_dev = std::max(max_dev, std::abs(u[0]));
  }
  std::printf("x step: command starts %d periods before the step, peak %.2f mm, final %.6f mm\n",
              c - static_cast<int>(first_move), max_dev, u[0]);
  // Linear hold: v_k = u_{k+1}, so the first command that can react is u at c - P + 1.
  EXPECT_GE(first_move, c - P);
  EXPECT_LT(first_move, c);
  EXPECT_LT(max_dev, 20.0);
  EXPECT_NEAR(u[0], 1.0, 1e-6);
}

TEST(GantryLpvFeedforward, BeltStiffnessFollowsEq6) {
  const GantryAxisLpvModel m = axis_model(false);
  EXPECT_NEAR(belt_stiffness_n_m(m, 0.0), m.params.k2_n_m, 1e-6);
  // x = 100 mm of L = 300 mm: mean of k_hat/(L - x) and k_hat/(L + x) = k2 L^2 / (L^2 - x^2).
  EXPECT_NEAR(belt_stiffness_n_m(m, 100.0), m.params.k2_n_m * 9.0 / 8.0, 1e-6);
}

}  // namespace
}  // namespace feedloop::control
