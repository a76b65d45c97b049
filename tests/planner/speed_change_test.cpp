// The thesis's speed-change cornering rule (closed-loop-gantry-thesis Sect. 2.2, Sect. 5.4):
// the junction speed v is the largest with |v u_next - v u_prev| <= max_speed_change_mm_s
// (vector norm over XYZ), capped by both moves' cruise speeds and by what acceleration can reach.
// Hand cases (formula, square, star, reversal, straight line) and the large star of Sect. 5.4 at
// 15 and 300 mm/s with its total time against a closed-form sum of trapezoids.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "planner/junction.hpp"
#include "planner_test_util.hpp"

namespace feedloop::planner {
namespace {

struct Collect : MoveSink {
  std::vector<PlannedMove> moves;
  void on_move(const PlannedMove& m) override { moves.push_back(m); }
};

std::vector<PlannedMove> plan(const PlannerConfig& c, const std::vector<Vec4>& points, double v, double a) {
  Collect sink;
  Planner p(c, sink);
  p.set_position(points[0]);
  for (size_t i = 1; i < points.size(); ++i) p.add_move({points[i], v, a, static_cast<int>(i)});
  p.flush();
  return sink.moves;
}

PlannerConfig speed_change_config(double dv_mm_s) {
  PlannerConfig c = test::cartesian_config();
  c.cornering = CorneringPolicy::speed_change;
  c.max_speed_change_mm_s = dv_mm_s;
  return c;
}

// |v u_next - v u_prev| at the junction after move i, from the emitted moves (XYZ).
double velocity_change_mm_s(const PlannedMove& p, const PlannedMove& n) {
  const double v = p.v_exit_mm_s;
  double s = 0.0;
  for (int k = 0; k < 3; ++k) s += (v * n.unit[k] - v * p.unit[k]) * (v * n.unit[k] - v * p.unit[k]);
  return std::sqrt(s);
}

// Sect. 5.4's large star: outer radius 35 mm, inner 14 mm, ten vertices from the tip at 90 deg
// (bench/control/trajectories.cpp star_path), centred on the bed, closed.
std::vector<Vec4> large_star() {
  std::vector<Vec4> pts;
  for (int k = 0; k <= 10; ++k) {
    const double a = M_PI / 2.0 + M_PI / 5.0 * (k % 10);
    const double r = k % 2 == 0 ? 35.0 : 14.0;
    pts.push_back({110.0 + r * std::cos(a), 110.0 + r * std::sin(a), 5.0, 0.0});
  }
  return pts;
}

// A trapezoid's time in closed form: v0 -> vc at a, cruise, vc -> v1 at a.
double trapezoid_time_s(double L, double v0, double vc, double v1, double a) {
  const double d_acc = (vc * vc - v0 * v0) / (2 * a), d_dec = (vc * vc - v1 * v1) / (2 * a);
  return (vc - v0) / a + (vc - v1) / a + (L - d_acc - d_dec) / vc;
}

TEST(SpeedChange, FormulaHandCases) {
  const double x[3] = {1, 0, 0}, y[3] = {0, 1, 0}, mx[3] = {-1, 0, 0};
  const double d36[3] = {std::cos(M_PI / 5), std::sin(M_PI / 5), 0};
  EXPECT_NEAR(std::sqrt(speed_change_v2(x, y, 15.0)), 15.0 / std::sqrt(2.0), 1e-12);  // 90 deg: 10.607
  EXPECT_NEAR(std::sqrt(speed_change_v2(x, mx, 15.0)), 7.5, 1e-12);                  // reversal: dv / 2
  EXPECT_NEAR(std::sqrt(speed_change_v2(x, d36, 15.0)), 15.0 / (2 * std::sin(M_PI / 10)), 1e-9);  // 24.27
  EXPECT_TRUE(std::isinf(speed_change_v2(x, x, 15.0)));                              // straight: unlimited
  // scales linearly with the allowed change
  EXPECT_NEAR(std::sqrt(speed_change_v2(x, y, 300.0)), 300.0 / std::sqrt(2.0), 1e-9);
}

TEST(SpeedChange, SquareCornersChangeVelocityByExactlyTheLimit) {
  for (double dv : {5.0, 15.0, 40.0}) {
    const auto m = plan(speed_change_config(dv), {{10, 10, 0, 0}, {110, 10, 0, 0}, {110, 110, 0, 0}, {10, 110, 0, 0}, {10, 10, 0, 0}},
                        150.0, 3000.0);
    ASSERT_EQ(m.size(), 4u);
    for (size_t i = 0; i + 1 < m.size(); ++i) {
      EXPECT_NEAR(m[i].v_exit_mm_s, dv / std::sqrt(2.0), 1e-9) << dv << " corner " << i;
      EXPECT_NEAR(velocity_change_mm_s(m[i], m[i + 1]), dv, 1e-9);
      EXPECT_NEAR(m[i].v_cruise_mm_s, 150.0, 1e-9);
    }
  }
}

TEST(SpeedChange, ReversalAllowsHalfTheChangeAndStraightIsUnlimited) {
  const auto r = plan(speed_change_config(15.0), {{10, 10, 0, 0}, {60, 10, 0, 0}, {20, 10, 0, 0}}, 150.0, 3000.0);
  ASSERT_EQ(r.size(), 2u);
  EXPECT_NEAR(r[0].v_exit_mm_s, 7.5, 1e-9);
  EXPECT_NEAR(velocity_change_mm_s(r[0], r[1]), 15.0, 1e-9);  // +7.5 to -7.5
  // a reversal in 3D (xyz diagonal)
  const auto r3 = plan(speed_change_config(15.0), {{10, 10, 1, 0}, {40, 40, 31, 0}, {20, 20, 11, 0}}, 150.0, 3000.0);
  ASSERT_EQ(r3.size(), 2u);
  EXPECT_NEAR(r3[0].v_exit_mm_s, 7.5, 1e-9);
  // straight through: the junction runs at the cruise speed
  const auto s = plan(speed_change_config(15.0), {{10, 10, 0, 0}, {60, 10, 0, 0}, {110, 10, 0, 0}}, 150.0, 3000.0);
  ASSERT_EQ(s.size(), 2u);
  EXPECT_NEAR(s[0].v_exit_mm_s, 150.0, 1e-9);
  // an almost straight junction (0.1 deg): limited by the cruise speed, not the rule (8594 mm/s)
  const double t = 0.1 * M_PI / 180.0;
  const auto a = plan(speed_change_config(15.0), {{10, 10, 0, 0}, {60, 10, 0, 0}, {60 + 50 * std::cos(t), 10 + 50 * std::sin(t), 0, 0}},
                      150.0, 3000.0);
  EXPECT_NEAR(a[0].v_exit_mm_s, 150.0, 1e-9);
  // the rule below the cruise speed: 179 deg turn -> 15 / (2 sin(89.5 deg))
  const double t2 = 179.0 * M_PI / 180.0;
  const auto b = plan(speed_change_config(15.0), {{10, 10, 0, 0}, {60, 10, 0, 0}, {60 + 40 * std::cos(t2), 10 + 40 * std::sin(t2), 0, 0}},
                      150.0, 3000.0);
  EXPECT_NEAR(b[0].v_exit_mm_s, 15.0 / (2.0 * std::sin(t2 / 2.0)), 1e-9);
}

// Acceleration binds: a corner after a short move from rest cannot exceed sqrt(2 a L).
TEST(SpeedChange, AccelerationStillBinds) {
  const auto m = plan(speed_change_config(300.0), {{10, 10, 0, 0}, {11, 10, 0, 0}, {11, 60, 0, 0}}, 150.0, 3000.0);
  ASSERT_EQ(m.size(), 2u);
  EXPECT_NEAR(m[0].v_exit_mm_s, std::sqrt(2.0 * 3000.0 * 1.0), 1e-9);  // 77.46 < 300 / sqrt 2
}

// Sect. 5.4: the large star at 150 mm/s, a = 3000, speed change 15 (the default) and 300 mm/s.
TEST(SpeedChange, LargeStarOfSection54) {
  const std::vector<Vec4> pts = large_star();
  double times[2] = {0, 0};
  int idx = 0;
  for (double dv : {15.0, 300.0}) {
    const auto m = plan(speed_change_config(dv), pts, 150.0, 3000.0);
    ASSERT_EQ(m.size(), 10u);
    double closed_form_s = 0.0, max_change = 0.0, min_v = 1e9, max_v = 0.0;
    for (size_t i = 0; i < m.size(); ++i) {
      EXPECT_NEAR(m[i].length_mm, m[0].length_mm, 1e-9);  // 25.06 mm edges
      closed_form_s += trapezoid_time_s(m[i].length_mm, m[i].v_entry_mm_s, m[i].v_cruise_mm_s, m[i].v_exit_mm_s, 3000.0);
      if (i + 1 == m.size()) break;
      double dot = 0.0;
      for (int k = 0; k < 3; ++k) dot += m[i].unit[k] * m[i + 1].unit[k];
      const double turn = std::acos(std::clamp(dot, -1.0, 1.0));
      const double expect = std::min(150.0, dv / (2.0 * std::sin(turn / 2.0)));  // the rule, written again
      EXPECT_NEAR(m[i].v_exit_mm_s, expect, 1e-9) << dv << " junction " << i;
      EXPECT_LE(velocity_change_mm_s(m[i], m[i + 1]), dv * (1 + 1e-12));
      max_change = std::max(max_change, velocity_change_mm_s(m[i], m[i + 1]));
      min_v = std::min(min_v, m[i].v_exit_mm_s);
      max_v = std::max(max_v, m[i].v_exit_mm_s);
    }
    const double t = m.back().end_time_s();
    EXPECT_NEAR(t, closed_form_s, 1e-9);
    std::printf("large star, speed change %3.0f mm/s: time %.4f s, junction speeds %.2f-%.2f mm/s, largest velocity "
                "change %.2f mm/s (thesis Sect. 5.4: %s)\n",
                dv, t, min_v, max_v, max_change, dv == 15.0 ? "2.2 s" : "1.7 s");
    times[idx++] = t;
  }
  // 300 mm/s: no corner slows down (2 v sin(turn/2) <= 300 for every turn), so the path is one
  // trapezoid over 10 edges: L/v + v/a.
  const double L = 10.0 * std::sqrt(35.0 * 35.0 + 14.0 * 14.0 - 2 * 35.0 * 14.0 * std::cos(M_PI / 5));
  EXPECT_NEAR(times[1], L / 150.0 + 150.0 / 3000.0, 1e-9);  // 1.7207 s
  EXPECT_GT(times[0], times[1] + 0.3);                      // the thesis: 2.2 vs 1.7 s
  std::printf("large star: speed change 300 saves %.1f %% (thesis: 23 %%)\n", 100.0 * (1.0 - times[1] / times[0]));
}

TEST(SpeedChange, ValidateRejectsNonPositiveLimit) {
  PlannerConfig c = speed_change_config(0.0);
  EXPECT_FALSE(c.validate().ok());
  c.max_speed_change_mm_s = 15.0;
  EXPECT_TRUE(c.validate().ok());
}

}  // namespace
}  // namespace feedloop::planner
