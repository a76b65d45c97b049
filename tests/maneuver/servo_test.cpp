// The sampled servo (zero-order hold): Table II's gains need a control period below about
// 1 / (0.6 K_d); at 0.2 ms it follows the fin layer as the continuous controller does.
#include <gtest/gtest.h>

#include "maneuver/gcode_path.hpp"
#include "maneuver/servo.hpp"
#include "maneuver/simulation.hpp"
#include "maneuver/test_part.hpp"

namespace feedloop::maneuver {
namespace {

std::vector<Vec3> fin_layer_m() {
  TestPartOptions tp;
  tp.layers = 1;
  GcodePathOptions gp;
  gp.layers = 1;
  gp.feature = "External perimeter";
  const auto wp_mm = extrusion_path_from_gcode(test_part_gcode(tp), "fin", gp);
  std::vector<Vec3> out;
  if (!wp_mm.ok()) return out;
  for (const Vec3& p : wp_mm.value()) out.push_back(p * 1e-3);
  return out;
}

Result<SimResult> run(double period_s, SpeedProfile prof, Parameterization param) {
  static const std::vector<Vec3> wp = fin_layer_m();
  auto path = PiecewiseLinearPath::create(wp, param);
  auto speed = SpeedAssignment::create(*path, prof, SpeedParams{});
  const CartesianDcPlant plant;
  ManeuverGains g;
  if (param == Parameterization::arc_length) g.mu *= 3.54e-3 * 3.54e-3;
  const ManeuverController ctl(plant, g);
  SimOptions so;
  so.record_every = 0;
  so.split_at_waypoints = param == Parameterization::arc_length;
  so.control_period_s = period_s;
  return simulate(*path, *speed, ctl, plant, so);
}

TEST(ManeuverServo, TableIIGainsDivergeAt1kHzAndHoldAt0p9ms) {
  auto at_1ms = run(1e-3, SpeedProfile::constant, Parameterization::unit);
  ASSERT_FALSE(at_1ms.ok());
  EXPECT_NE(at_1ms.error().message.find("diverged"), std::string::npos);
  auto at_09ms = run(0.9e-3, SpeedProfile::constant, Parameterization::unit);
  ASSERT_TRUE(at_09ms.ok()) << at_09ms.error().message;
  EXPECT_TRUE(at_09ms->finished);
  EXPECT_LT(at_09ms->max_cross_m, 2e-4);
}

TEST(ManeuverServo, At5kHzFollowsLikeTheContinuousController) {
  for (auto [prof, param] : {std::pair{SpeedProfile::sharp_corner, Parameterization::unit},
                             std::pair{SpeedProfile::sharp_corner_arc, Parameterization::arc_length}}) {
    auto cont = run(0.0, prof, param);
    auto samp = run(2e-4, prof, param);
    ASSERT_TRUE(cont.ok() && samp.ok());
    ASSERT_TRUE(samp->finished);
    EXPECT_NEAR(samp->total_time_s, cont->total_time_s, 0.002 * cont->total_time_s) << to_string(prof);
    EXPECT_NEAR(samp->iae_cross_m_s, cont->iae_cross_m_s, 0.05 * cont->iae_cross_m_s) << to_string(prof);
    EXPECT_LT(samp->max_cross_m, 1.5 * cont->max_cross_m) << to_string(prof);
    EXPECT_EQ(samp->skipped_segments, 0u);
  }
}

TEST(ManeuverServo, SplitUpdateEntersEveryWaypointOfAShortNotch) {
  // A 1 ms period over 0.02 mm segments: the split servo still enters each one in order.
  const std::vector<Vec3> wp{{0, 0, 0},       {0.01, 0, 0},    {0.01, 0.02e-3, 0}, {0.01003, 0.02e-3, 0},
                             {0.01003, 0, 0}, {0.02003, 0, 0}, {0.02003, 0.01, 0}};
  auto path = PiecewiseLinearPath::create(wp, Parameterization::arc_length);
  auto speed = SpeedAssignment::create(*path, SpeedProfile::constant, SpeedParams{});
  const CartesianDcPlant plant;
  ManeuverGains g;
  g.mu = 0.0;
  const ManeuverController ctl(plant, g);
  ManeuverServo servo(*path, *speed, ctl, true);
  PlantState x;
  x.x1_m = path->point(0);
  size_t prev = 1, steps = 0;
  while (!servo.finished() && steps < 1000) {
    // An ideal plant that sits on the path: only theta's stepping is under test here.
    x.x1_m = path->yd(servo.state().theta, servo.segment());
    servo.update(x, 1e-3);
    ASSERT_LE(servo.segment(), path->segments());
    EXPECT_GE(servo.segment(), prev);
    prev = servo.segment();
    ++steps;
  }
  EXPECT_TRUE(servo.finished());
  EXPECT_EQ(servo.skipped_segments(), 0u);
  EXPECT_EQ(prev, path->segments());
}

}  // namespace
}  // namespace feedloop::maneuver
