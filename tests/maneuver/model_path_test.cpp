// The DC-motor printer model (Eq. 11-20, Table I) and the piecewise-linear path (Eq. 21-25).
#include <gtest/gtest.h>

#include <cmath>

#include "maneuver/path.hpp"
#include "maneuver/printer_model.hpp"

namespace feedloop::maneuver {
namespace {

TEST(ManeuverPrinterModel, TableIMatrices) {
  const PrinterMatrices m = printer_matrices(CartesianDcParams{});
  // J_m / r^2 = 5e-6 / 1e-4 = 0.05 kg on every axis (Eq. 16).
  EXPECT_NEAR(m.m_kg.x(), 0.45, 1e-12);
  EXPECT_NEAR(m.m_kg.y(), 0.85, 1e-12);
  EXPECT_NEAR(m.m_kg.z(), 0.65, 1e-12);
  EXPECT_NEAR(m.d_n_s_m.x(), 1.1, 1e-12);  // B / r^2 (Eq. 17)
  EXPECT_NEAR(m.k1_n_v, 10.0, 1e-12);      // K_m / (r R_a) (Eq. 18)
}

TEST(ManeuverPrinterModel, Rk4MatchesTheFirstOrderVelocityResponse) {
  const CartesianDcPlant plant;
  PlantState s;
  const CartesianDcParams p;
  const double v_volts = 0.05;
  Vec3 w(v_volts, -v_volts, plant.gravity_offset_v());  // z: Eq. 14 offset only -> no motion
  const double dt = 1e-3;
  for (int i = 0; i < 500; ++i) plant.step_rk4(s, w, dt);
  const PrinterMatrices m = plant.matrices();
  for (int a = 0; a < 2; ++a) {
    // M v' + D v = k_1 V: v(t) = k_1 V / D (1 - exp(-D t / M)), x(t) its integral.
    const double vin = a == 0 ? v_volts : -v_volts;
    const double vinf = m.k1_n_v * vin / m.d_n_s_m[a];
    const double tau = m.m_kg[a] / m.d_n_s_m[a];
    const double t = 0.5;
    EXPECT_NEAR(s.x2_m_s[a], vinf * (1.0 - std::exp(-t / tau)), 1e-9);
    EXPECT_NEAR(s.x1_m[a], vinf * (t - tau * (1.0 - std::exp(-t / tau))), 1e-9);
  }
  EXPECT_NEAR(s.x1_m.z(), 0.0, 1e-12);
  EXPECT_NEAR(s.x2_m_s.z(), 0.0, 1e-12);
  (void)p;
}

TEST(ManeuverPath, UnitAndArcLengthParameterisations) {
  const std::vector<Vec3> wp{{0, 0, 0}, {0.03, 0, 0}, {0.03, 0.04, 0}};
  auto unit = PiecewiseLinearPath::create(wp, Parameterization::unit);
  auto arc = PiecewiseLinearPath::create(wp, Parameterization::arc_length);
  ASSERT_TRUE(unit.ok());
  ASSERT_TRUE(arc.ok());
  EXPECT_EQ(unit->segments(), 2u);
  EXPECT_DOUBLE_EQ(unit->theta_end(), 2.0);
  EXPECT_NEAR(arc->theta_end(), 0.07, 1e-15);
  // Eq. 25: dy_d/dtheta = Delta_n with unit theta; a unit tangent with arc length.
  EXPECT_NEAR((unit->dyd(2) - Vec3(0, 0.04, 0)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((arc->dyd(2) - Vec3(0, 1, 0)).norm(), 0.0, 1e-15);
  // The same point halfway along segment 2.
  EXPECT_NEAR((unit->yd(1.5, 2) - Vec3(0.03, 0.02, 0)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((arc->yd(0.05, 2) - Vec3(0.03, 0.02, 0)).norm(), 0.0, 1e-15);
  EXPECT_EQ(unit->segment_at(0.999), 1u);
  EXPECT_EQ(unit->segment_at(1.0), 2u);
  EXPECT_EQ(unit->segment_at(5.0), 2u);   // clamped
  EXPECT_EQ(unit->segment_at(-1.0), 1u);  // clamped
  EXPECT_NEAR(unit->arc_length(1.5, 2), 0.05, 1e-15);
  EXPECT_NEAR(unit->corner_angle_deg(1), 90.0, 1e-9);  // Eq. 64
}

TEST(ManeuverPath, RejectsDegenerateInputAndMergesDuplicates) {
  auto dup = PiecewiseLinearPath::create({{0, 0, 0}, {0, 0, 0}, {0.01, 0, 0}}, Parameterization::unit);
  ASSERT_TRUE(dup.ok());
  EXPECT_EQ(dup->segments(), 1u);
  auto one = PiecewiseLinearPath::create({{0, 0, 0}, {0, 0, 0}}, Parameterization::unit);
  ASSERT_FALSE(one.ok());
  EXPECT_NE(one.error().message.find("two distinct waypoints"), std::string::npos);
  auto nan = PiecewiseLinearPath::create({{0, 0, 0}, {NAN, 0, 0}}, Parameterization::arc_length);
  ASSERT_FALSE(nan.ok());
  EXPECT_NE(nan.error().message.find("waypoint 1"), std::string::npos);
}

}  // namespace
}  // namespace feedloop::maneuver
