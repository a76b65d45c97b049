// The streaming servo (stream.hpp), what the daemon's servo thread runs: on a path known in full
// it reproduces ManeuverServo with split steps period by period; fed a few millimetres ahead while
// it runs (old waypoints released) it gives the same voltages; starved, it stops at the end of the
// known path and holds it, then goes on when waypoints arrive, entering every segment.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "maneuver/gcode_path.hpp"
#include "maneuver/servo.hpp"
#include "maneuver/stream.hpp"
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

struct FinRig {
  std::vector<Vec3> wp = fin_layer_m();
  Result<PiecewiseLinearPath> path = PiecewiseLinearPath::create(wp, Parameterization::arc_length);
  StreamSpeed sspeed{SpeedProfile::sharp_corner_arc, SpeedParams{}};
  Result<SpeedAssignment> speed = SpeedAssignment::create(*path, sspeed.profile, sspeed.params);
  CartesianDcPlant plant;
  ManeuverGains gains = [] {
    ManeuverGains g;
    g.mu = 1000.0 * 3.54e-3 * 3.54e-3;  // Table II scaled by the mean segment length squared
    return g;
  }();
  ManeuverController ctl{plant, gains};
  StreamWaypoint wp_at(size_t n) const { return {path->point(n), speed->k(n), 0.0, static_cast<int>(n)}; }
};

constexpr double kPeriod = 2e-4;

TEST(ManeuverStream, WholePathReproducesTheSplitServo) {
  FinRig s;
  ASSERT_TRUE(s.path.ok() && s.speed.ok());
  ASSERT_GE(s.path->segments(), 50u);
  PathWindow win(s.path->segments() + 1, Parameterization::arc_length);
  for (size_t n = 0; n <= s.path->segments(); ++n) ASSERT_TRUE(win.push(s.wp_at(n)));
  StreamServo stream(win, s.sspeed, s.ctl);
  stream.start_at(win.first());
  ManeuverServo ref(*s.path, *s.speed, s.ctl, true);
  PlantState x1, x2;
  x1.x1_m = x2.x1_m = s.path->point(0);
  double max_dv = 0.0, max_v = 0.0;
  int periods = 0;
  for (; periods < 200000 && !ref.finished(); ++periods) {
    const Vec3 w_ref = ref.update(x1, kPeriod);
    const Vec3 w = stream.update(x2, kPeriod);
    max_dv = std::max(max_dv, (w - w_ref).cwiseAbs().maxCoeff());
    max_v = std::max(max_v, w_ref.head<2>().cwiseAbs().maxCoeff());
    for (int i = 0; i < 2; ++i) {
      s.plant.step_rk4(x1, w_ref, kPeriod / 2);
      s.plant.step_rk4(x2, w, kPeriod / 2);
    }
  }
  std::printf("fin layer, %zu segments: %d periods, max |V_stream - V_servo| %.3g V (max |V| %.3g V)\n",
              s.path->segments(), periods, max_dv, max_v);
  EXPECT_TRUE(ref.finished());
  EXPECT_LT(max_dv, 1e-9 * max_v);
  // Then the stream holds the last waypoint (the reference simply stops).
  for (int i = 0; i < 2000; ++i) {
    const Vec3 w = stream.update(x2, kPeriod);
    for (int k = 0; k < 2; ++k) s.plant.step_rk4(x2, w, kPeriod / 2);
  }
  EXPECT_TRUE(stream.holding());
  EXPECT_EQ(stream.segments_entered(), s.path->segments());
  EXPECT_LT((x2.x1_m - s.path->point(s.path->segments())).norm(), 1e-7);
}

TEST(ManeuverStream, FedAheadWhileRunningGivesTheSameVoltages) {
  FinRig s;
  ASSERT_TRUE(s.path.ok() && s.speed.ok());
  const size_t N = s.path->segments();
  PathWindow full(N + 1, Parameterization::arc_length), small(64, Parameterization::arc_length);
  for (size_t n = 0; n <= N; ++n) ASSERT_TRUE(full.push(s.wp_at(n)));
  size_t fed = 0;
  auto feed = [&](double s_now_m) {  // keep 4 mm (twice the arc reach) known ahead, or all of it
    while (fed <= N && (fed < 2 || small.s_m(small.last()) - s_now_m < 4e-3 || fed == N) && !small.full()) {
      ASSERT_TRUE(small.push(s.wp_at(fed)));
      ++fed;
    }
  };
  feed(0.0);
  StreamServo a(full, s.sspeed, s.ctl), b(small, s.sspeed, s.ctl);
  a.start_at(full.first());
  b.start_at(small.first());
  PlantState xa, xb;
  xa.x1_m = xb.x1_m = s.path->point(0);
  double max_dv = 0.0;
  size_t max_size = 0;
  for (int i = 0; i < 200000 && !(a.holding() && i > 10); ++i) {
    const Vec3 wa = a.update(xa, kPeriod);
    const Vec3 wb = b.update(xb, kPeriod);
    max_dv = std::max(max_dv, (wa - wb).cwiseAbs().maxCoeff());
    for (int k = 0; k < 2; ++k) {
      s.plant.step_rk4(xa, wa, kPeriod / 2);
      s.plant.step_rk4(xb, wb, kPeriod / 2);
    }
    small.release_before(b.oldest_needed());
    max_size = std::max(max_size, small.size());
    feed(b.s_m());
  }
  std::printf("fed 4 mm ahead: window up to %zu of 64 waypoints, max |dV| %.3g V\n", max_size, max_dv);
  EXPECT_EQ(fed, N + 1);
  EXPECT_TRUE(b.holding());
  EXPECT_EQ(b.segments_entered(), N);
  EXPECT_LT(max_dv, 1e-9);
  EXPECT_LT(max_size, 64u);
}

TEST(ManeuverStream, StarvedItStopsHoldsAndGoesOnWithoutSkipping) {
  const CartesianDcPlant plant;
  ManeuverGains g;
  g.mu = 1e-3;
  const ManeuverController ctl(plant, g);
  const StreamSpeed sp{SpeedProfile::sharp_corner_arc, SpeedParams{}};
  PathWindow win(16, Parameterization::arc_length);
  // 10 mm along x, then a 0.02 mm notch (two 90-degree corners) and on: the notch comes later.
  ASSERT_TRUE(win.push({Vec3(0, 0, 0), 1.0, 0.0, 1}));
  ASSERT_TRUE(win.push({Vec3(10e-3, 0, 0), 1.0, 1.0, 2}));
  StreamServo servo(win, sp, ctl);
  servo.start_at(win.first());
  PlantState x;
  double max_cross = 0.0;
  auto run = [&](double t_s) {
    for (int i = 0; i < static_cast<int>(t_s / 1e-3); ++i) {
      const Vec3 w = servo.update(x, 1e-3 / 3);  // 3 kHz: K_d T = 0.56
      for (int k = 0; k < 3; ++k) plant.step_rk4(x, w, 1e-3 / 9);
      max_cross = std::max(max_cross, std::abs(servo.error().cross_m));
    }
  };
  run(0.5);  // 10 mm at up to 0.1 m/s, slowing into the stop
  EXPECT_TRUE(servo.holding());
  EXPECT_NEAR(x.x1_m.x(), 10e-3, 1e-6);
  EXPECT_NEAR(servo.e_mm(), 1.0, 1e-12);
  run(0.2);  // holds
  EXPECT_NEAR(x.x1_m.x(), 10e-3, 1e-7);
  EXPECT_LT(x.x2_m_s.norm(), 1e-5);
  ASSERT_TRUE(win.push({Vec3(10e-3, 0.02e-3, 0), 1.0, 1.0, 3}));
  ASSERT_TRUE(win.push({Vec3(10.02e-3, 0.02e-3, 0), 1.0, 1.0, 4}));
  ASSERT_TRUE(win.push({Vec3(10.02e-3, 0, 0), 1.0, 1.0, 5}));
  ASSERT_TRUE(win.push({Vec3(15e-3, 0, 0), 1.0, 2.0, 6}));
  run(0.4);
  EXPECT_TRUE(servo.holding());
  EXPECT_EQ(servo.segments_entered(), 5u);  // every segment, the notch's 0.02 mm ones included
  EXPECT_NEAR(x.x1_m.x(), 15e-3, 1e-6);
  EXPECT_NEAR(servo.e_mm(), 2.0, 1e-12);
  std::printf("starved stream: max cross-track %.3g um\n", max_cross * 1e6);
  EXPECT_LT(max_cross, 5e-6);
}

}  // namespace
}  // namespace feedloop::maneuver
