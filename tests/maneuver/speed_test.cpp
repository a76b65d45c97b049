// Speed assignments: Eq. 63, Eq. 66-68 (against planner::sharp_corner_speed), their derivatives,
// and the arc-length variant on short segments.
#include <gtest/gtest.h>

#include <cmath>

#include "maneuver/speed_assignment.hpp"
#include "planner/junction.hpp"

namespace feedloop::maneuver {
namespace {

// A path with a 90-degree corner, a gentle 3-degree one and a 12.5-degree one (Eq. 66 classes).
std::vector<Vec3> corners_path() {
  const double d3 = 3.0 * M_PI / 180.0, d155 = 15.5 * M_PI / 180.0;
  std::vector<Vec3> p{{0, 0, 0}, {0.02, 0, 0}, {0.02, 0.01, 0}};
  p.push_back(p.back() + 0.01 * Vec3(-std::sin(d3), std::cos(d3), 0));
  p.push_back(p.back() + 0.005 * Vec3(-std::sin(d155), std::cos(d155), 0));
  return p;
}

TEST(ManeuverSpeed, ConstantIsEq63) {
  auto path = PiecewiseLinearPath::create(corners_path(), Parameterization::unit);
  SpeedParams sp;
  auto v = SpeedAssignment::create(*path, SpeedProfile::constant, sp);
  ASSERT_TRUE(v.ok());
  for (size_t n = 1; n <= path->segments(); ++n) {
    const SpeedValue s = v->at(*path, path->theta(n - 1) + 0.3, n);
    EXPECT_NEAR(s.v_s, sp.m_s_m_s / path->segment_length_m(n), 1e-12);  // Eq. 63
    EXPECT_EQ(s.dv_s_dtheta, 0.0);
  }
}

TEST(ManeuverSpeed, SharpCornerWeightsAndCornerSpeedMatchThePlanner) {
  auto path = PiecewiseLinearPath::create(corners_path(), Parameterization::unit);
  SpeedParams sp;
  auto v = SpeedAssignment::create(*path, SpeedProfile::sharp_corner, sp);
  ASSERT_TRUE(v.ok());
  EXPECT_EQ(v->k(0), 1.0);
  EXPECT_EQ(v->k(1), 1.0);                    // 90 degrees: very sharp
  EXPECT_EQ(v->k(2), 0.0);                    // 3 degrees: non-sharp
  EXPECT_NEAR(v->k(3), (12.5 - 5.0) / 15.0, 1e-9);  // Eq. 66 interpolation (15.5 - 3 degrees)
  EXPECT_EQ(v->k(4), 1.0);                    // k_N
  // Path speed just before waypoint n equals the planner's Eq. 67 corner speed.
  for (size_t n = 1; n < path->segments(); ++n) {
    const double alpha = path->corner_angle_deg(n);
    const double expect = planner::sharp_corner_speed(sp.m_s_m_s, alpha, sp.sharp);
    const SpeedValue s = v->at(*path, path->theta(n) - 1e-12, n);
    EXPECT_NEAR(s.v_s * path->segment_length_m(n), expect, 1e-9) << "corner " << n;
  }
  auto every = SpeedAssignment::create(*path, SpeedProfile::every_transition, sp);
  EXPECT_NEAR(every->at(*path, path->theta(2) - 1e-12, 2).factor, planner::sharp_corner_h(0.0, sp.sharp), 1e-9);
}

TEST(ManeuverSpeed, DerivativesMatchFiniteDifferences) {
  for (auto param : {Parameterization::unit, Parameterization::arc_length}) {
    auto path = PiecewiseLinearPath::create(corners_path(), param);
    for (auto prof : {SpeedProfile::every_transition, SpeedProfile::sharp_corner, SpeedProfile::sharp_corner_arc}) {
      SpeedParams sp;
      sp.a1_m = 0.5e-3;  // wide enough for a finite difference to resolve
      sp.a2_m = 0.1e-3;
      sp.reach_m = 3.3e-3;  // f has a kink (not a jump) where a corner leaves the reach
      auto v = SpeedAssignment::create(*path, prof, sp);
      ASSERT_TRUE(v.ok());
      for (size_t n = 1; n <= path->segments(); ++n) {
        const double span = path->theta(n) - path->theta(n - 1);
        for (double u : {0.003, 0.04, 0.2, 0.45, 0.55, 0.8, 0.96, 0.997}) {
          const double th = path->theta(n - 1) + u * span, h = 1e-7 * span;
          const double fd = (v->at(*path, th + h, n).v_s - v->at(*path, th - h, n).v_s) / (2 * h);
          const double an = v->at(*path, th, n).dv_s_dtheta;
          EXPECT_NEAR(an, fd, 1e-5 * std::abs(fd) + 1e-6 * v->at(*path, th, n).v_s / span)
              << to_string(prof) << " segment " << n << " u " << u;
        }
      }
    }
  }
}

TEST(ManeuverSpeed, ArcVariantSeesASharpCornerPastAShortSegmentAndIsContinuous) {
  // 20 mm, then a 0.05 mm segment (2 deg turn: non-sharp), then a 90-degree corner.
  const double d2 = 2.0 * M_PI / 180.0;
  std::vector<Vec3> p{{0, 0, 0}, {0.02, 0, 0}};
  p.push_back(p.back() + 0.05e-3 * Vec3(std::cos(d2), std::sin(d2), 0));
  p.push_back(p.back() + Vec3(0, 0.02, 0));
  auto path = PiecewiseLinearPath::create(p, Parameterization::arc_length);
  SpeedParams sp;
  auto arc = SpeedAssignment::create(*path, SpeedProfile::sharp_corner_arc, sp);
  auto paper = SpeedAssignment::create(*path, SpeedProfile::sharp_corner, sp);
  ASSERT_TRUE(arc.ok() && paper.ok());
  EXPECT_EQ(arc->k(1), 0.0);
  EXPECT_EQ(arc->k(2), 1.0);
  // At p_1, 0.05 mm before the 90-degree corner: the arc variant is already slow (the corner is
  // within reach), Eq. 67 runs at full speed there (k_1 = 0, h(1/2) ~ 1).
  const double f_arc = arc->at(*path, path->theta(1), 2).factor;
  const double f_paper = paper->at(*path, path->theta(1), 2).factor;
  EXPECT_LT(f_arc, 0.3);
  EXPECT_GT(f_paper, 0.99);
  // Continuous across waypoints and along the path (no jump larger than the local slope allows).
  const double ds = 1e-7;  // the steepest slope is 1/(pi a2_m) per metre: 0.006 per step
  double prev = arc->at(*path, 0.019, 1).factor;
  for (double s = 0.019 + ds; s < 0.021; s += ds) {
    const double f = arc->at(*path, s, path->segment_at(s)).factor;
    ASSERT_LT(std::abs(f - prev), 0.02) << "at s = " << s;
    prev = f;
  }
}

TEST(ManeuverSpeed, RejectsBadParameters) {
  auto path = PiecewiseLinearPath::create(corners_path(), Parameterization::unit);
  SpeedParams sp;
  sp.m_s_m_s = 0.0;
  EXPECT_FALSE(SpeedAssignment::create(*path, SpeedProfile::constant, sp).ok());
  sp = {};
  sp.sharp.alpha_b_deg = 4.0;
  EXPECT_FALSE(SpeedAssignment::create(*path, SpeedProfile::sharp_corner, sp).ok());
  sp = {};
  sp.reach_m = 0.0;
  EXPECT_FALSE(SpeedAssignment::create(*path, SpeedProfile::sharp_corner_arc, sp).ok());
}

}  // namespace
}  // namespace feedloop::maneuver
