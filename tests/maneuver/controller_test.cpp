// Stability of the maneuvering controller: the Lyapunov function V of Eq. 51 along simulated runs,
// and Eq. 55 (V' = -1/2 z^T Q z - omega_s^2 / mu) at sampled states.
#include <gtest/gtest.h>

#include <cmath>

#include "maneuver/controller.hpp"
#include "maneuver/simulation.hpp"

namespace feedloop::maneuver {
namespace {

// dV/dt along the closed loop by a central difference of V over a tiny RK-free Euler step.
double v_dot_numeric(const ManeuverController& ctl, const CartesianDcPlant& plant, const PiecewiseLinearPath& path,
                     const SpeedAssignment& speed, const PlantState& x, const ManeuverState& c, size_t n) {
  const double h = 1e-8;
  auto shifted = [&](double k) {
    const ManeuverOutput o = ctl.evaluate(path, speed, x, c, n);
    const PlantDerivative d = plant.derivative(x, o.w_v);
    const PlantState xs{x.x1_m + k * d.dx1_m_s, x.x2_m_s + k * d.dx2_m_s2};
    const ManeuverState cs{c.theta + k * o.dtheta, c.omega_s + k * o.domega_s};
    return ctl.evaluate(path, speed, xs, cs, n).lyapunov;
  };
  return (shifted(h) - shifted(-h)) / (2 * h);
}

TEST(ManeuverController, LyapunovDerivativeIsEq55) {
  const CartesianDcPlant plant;
  const ManeuverController ctl(plant, ManeuverGains{});
  EXPECT_NEAR(ctl.p1(), 1e-3, 1e-15);         // Q_1 / (2 K_p)
  EXPECT_NEAR(ctl.p2(), 1.0 / 3334.0, 1e-15);  // Q_2 / (2 K_d)
  auto path = PiecewiseLinearPath::create({{0, 0, 0}, {0.05, 0.02, 0.001}}, Parameterization::unit);
  for (auto prof : {SpeedProfile::constant, SpeedProfile::sharp_corner}) {
    auto speed = SpeedAssignment::create(*path, prof, SpeedParams{});
    for (int i = 0; i < 20; ++i) {  // deterministic spread of states
      const double a = 0.37 * i, b = 1.3 * i;
      const PlantState x{Vec3(1e-3 * std::sin(a), 2e-3 * std::cos(b), 5e-4 * std::sin(a + b)),
                         Vec3(0.05 * std::cos(a), -0.02 * std::sin(b), 0.01)};
      const ManeuverState c{0.1 + 0.04 * i, 0.3 * std::sin(2.0 * a)};
      const ManeuverOutput o = ctl.evaluate(*path, *speed, x, c, 1);
      const double expect = -0.5 * (o.z1_m.squaredNorm() + o.z2_m_s.squaredNorm()) -
                            c.omega_s * c.omega_s / ctl.gains().mu;  // Eq. 55 with Q_i = I
      const double got = v_dot_numeric(ctl, plant, *path, *speed, x, c, 1);
      EXPECT_NEAR(got, expect, 1e-6 * std::abs(expect) + 1e-12) << to_string(prof) << " state " << i;
      EXPECT_LT(got, 0.0);
    }
  }
}

// Runs the closed loop from an initial offset and checks that V never grows over a step that
// stays on one segment (at a waypoint dy_d/dtheta jumps and so may V).
void expect_v_decreasing(Parameterization param, SpeedProfile prof, bool split) {
  const std::vector<Vec3> wp{{0, 0, 0}, {0.02, 0, 0}, {0.02, 0.015, 0}, {0.035, 0.03, 0.0004}};
  auto path = PiecewiseLinearPath::create(wp, param);
  auto speed = SpeedAssignment::create(*path, prof, SpeedParams{});
  ASSERT_TRUE(path.ok() && speed.ok());
  const CartesianDcPlant plant;
  ManeuverGains g;
  if (param == Parameterization::arc_length) g.mu = 1000.0 * 0.02 * 0.02;  // as bench_maneuver scales it
  const ManeuverController ctl(plant, g);
  SimOptions so;
  // 20 us: the arc sigmoid (a2_m = 5 um) is steep; at 100 us the RK4 error shows as rises of V
  // of a few 1e-9 V(0) just before corners.
  so.dt_s = 2e-5;
  so.record_every = 1;
  so.split_at_waypoints = split;
  so.start_at_path = false;
  so.initial.x1_m = Vec3(-2e-3, 1.5e-3, 1e-3);  // start off the path
  auto r = simulate(*path, *speed, ctl, plant, so);
  ASSERT_TRUE(r.ok());
  ASSERT_TRUE(r->finished);
  const auto& s = r->samples;
  ASSERT_GT(s.size(), 1000u);
  size_t checked = 0, crossings = 0;
  size_t rises = 0;
  double worst_rise = 0.0;
  for (size_t i = 1; i < s.size(); ++i) {
    if (s[i].segment != s[i - 1].segment) {
      ++crossings;
      continue;
    }
    // Tolerance: integration error, 1e-6 of V and 1e-9 of the initial V.
    const double rise = s[i].lyapunov - s[i - 1].lyapunov;
    if (rise > 1e-6 * s[i - 1].lyapunov + 1e-9 * s[0].lyapunov) {
      ++rises;
      worst_rise = std::max(worst_rise, rise / s[i - 1].lyapunov);
    }
    ++checked;
  }
  EXPECT_EQ(crossings, 2u);
  EXPECT_GT(checked, 10000u);
  EXPECT_EQ(rises, 0u) << "V rose on a segment, worst by a factor " << worst_rise;
  // From the initial offset V falls by orders of magnitude within 20 ms (the omega_s term,
  // filtered at lambda = 30 rad/s, decays last).
  EXPECT_GT(s[0].lyapunov, 1e3 * s[1000].lyapunov);
}

TEST(ManeuverController, LyapunovDecreasesAlongARunUnitConstant) {
  expect_v_decreasing(Parameterization::unit, SpeedProfile::constant, false);
}
TEST(ManeuverController, LyapunovDecreasesAlongARunUnitSharpCorner) {
  expect_v_decreasing(Parameterization::unit, SpeedProfile::sharp_corner, false);
}
TEST(ManeuverController, LyapunovDecreasesAlongARunArcLengthVariant) {
  expect_v_decreasing(Parameterization::arc_length, SpeedProfile::sharp_corner_arc, true);
}

}  // namespace
}  // namespace feedloop::maneuver
