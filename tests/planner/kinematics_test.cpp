// Kinematics: delta inverse/forward kinematics, the Jacobian of Eq. 12 and the joint velocities
// against finite differences, reachability of points and whole segments; cartesian/corexy maps.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "planner/delta_kinematics.hpp"
#include "planner/linear_kinematics.hpp"
#include "planner_test_util.hpp"

namespace feedloop::planner {
namespace {

DeltaKinematics canonical_delta() {
  const PlannerConfig c = test::delta_config();
  return DeltaKinematics(c.delta, c.min_position_mm[kZ], c.max_position_mm[kZ]);
}

// DESIGN.md validation positions at z = 30 mm.
const Vec3 kValidation[] = {{0.0, 0.0, 30.0}, {-80.0, 0.0, 30.0}, {40.0, -69.0, 30.0}, {40.0, 69.0, 30.0}};

TEST(DeltaKinematics, InverseSatisfiesTheArmConstraintsAndForwardInvertsIt) {
  const DeltaKinematics k = canonical_delta();
  for (const Vec3& p : kValidation) {
    ASSERT_TRUE(k.check_point(p)) << p[0] << "," << p[1];
    const Joints q = k.inverse(p);
    for (int i = 0; i < 3; ++i) {
      const auto t = k.tower_xy(i);
      const double sz = p[2] + 20.0 - q[i];  // Eq. 7
      const double c = (p[0] - t[0]) * (p[0] - t[0]) + (p[1] - t[1]) * (p[1] - t[1]) + sz * sz;
      EXPECT_NEAR(c, 300.0 * 300.0, 1e-7);  // Eq. 3-5
      EXPECT_LT(sz, 0.0);                    // carriages above the effector
    }
    Result<Vec3> back = k.forward(q);
    ASSERT_TRUE(back.ok());
    for (int i = 0; i < 3; ++i) EXPECT_NEAR((*back)[i], p[i], 1e-9);
  }
  // tower A on +x: the centre is at distance R from it; q_A = z + H + sqrt(L^2 - R^2)
  const Joints q = k.inverse({0.0, 0.0, 0.0});
  EXPECT_NEAR(q[0], 20.0 + std::sqrt(300.0 * 300.0 - 145.0 * 145.0), 1e-12);
  EXPECT_NEAR(k.tower_xy(1)[0], 145.0 * std::cos(2.0 * M_PI / 3.0), 1e-12);
}

TEST(DeltaKinematics, JacobianMatchesFiniteDifferencesOfForwardKinematics) {
  const DeltaKinematics k = canonical_delta();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> xy(-90.0, 90.0), z(0.0, 200.0);
  double worst = 0.0;
  for (int n = 0; n < 200; ++n) {
    const Vec3 p{xy(rng), xy(rng), z(rng)};
    if (!k.check_point(p)) continue;
    const Eigen::Matrix3d J = k.jacobian(p);  // Eq. 12: Xdot = J qdot
    const Joints q = k.inverse(p);
    const double h = 1e-5;
    for (int j = 0; j < 3; ++j) {
      Joints qp = q, qm = q;
      qp[j] += h;
      qm[j] -= h;
      const Vec3 xp = *k.forward(qp), xm = *k.forward(qm);
      for (int i = 0; i < 3; ++i) {
        const double fd = (xp[i] - xm[i]) / (2.0 * h);
        worst = std::max(worst, std::abs(fd - J(i, j)));
      }
    }
    // joint_velocity is J^-1 applied to a Cartesian velocity: check both ways.
    const Vec3 v{12.0, -7.0, 3.0};
    const Joints qd = k.joint_velocity(p, v);
    const Eigen::Vector3d back = J * Eigen::Vector3d(qd[0], qd[1], qd[2]);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(back[i], v[i], 1e-9);
    // and against finite differences of the inverse kinematics
    const Joints a = k.inverse({p[0] + h * v[0], p[1] + h * v[1], p[2] + h * v[2]});
    const Joints b = k.inverse({p[0] - h * v[0], p[1] - h * v[1], p[2] - h * v[2]});
    for (int i = 0; i < 3; ++i) EXPECT_NEAR((a[i] - b[i]) / (2.0 * h), qd[i], 1e-5);
  }
  EXPECT_LT(worst, 1e-5);
}

TEST(DeltaKinematics, RejectsPointsOutsideTheWorkspaceWithAClearMessage) {
  const DeltaKinematics k = canonical_delta();
  Status r = k.check_point({140.0, 0.0, 10.0});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("print radius"), std::string::npos) << r.error().message;
  Status z = k.check_point({0.0, 0.0, 301.0});
  ASSERT_FALSE(z.ok());
  EXPECT_NE(z.error().message.find("travel limits"), std::string::npos);
  EXPECT_TRUE(k.check_point({0.0, 0.0, 300.0}).ok());
}

TEST(DeltaKinematics, SegmentCheckFindsCarriageOvertravelBetweenReachableEnds) {
  // q_A is largest where the path passes closest to tower A: (60, -60) -> (60, 60) peaks at (60, 0).
  PlannerConfig c = test::delta_config();
  DeltaKinematics probe(c.delta, 0.0, 300.0);
  const double q_end = probe.inverse({60.0, 60.0, 0.0})[0];
  const double q_mid = probe.inverse({60.0, 0.0, 0.0})[0];
  ASSERT_GT(q_mid, q_end + 5.0);
  c.delta.carriage_max_mm = 0.5 * (q_end + q_mid);
  DeltaKinematics k(c.delta, 0.0, 300.0);
  EXPECT_TRUE(k.check_point({60.0, -60.0, 0.0}).ok());
  EXPECT_TRUE(k.check_point({60.0, 60.0, 0.0}).ok());
  Status s = k.check_segment({60.0, -60.0, 0.0}, {60.0, 60.0, 0.0});
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("carriage A"), std::string::npos) << s.error().message;
}

TEST(LinearKinematics, CoreXYMapsAndInverts) {
  LinearKinematics k(KinematicsKind::corexy, {0, 0, 0, 0}, {200, 200, 200, 0});
  const Joints q = k.inverse({10.0, 3.0, 5.0});
  EXPECT_DOUBLE_EQ(q[0], 13.0);
  EXPECT_DOUBLE_EQ(q[1], 7.0);
  EXPECT_DOUBLE_EQ(q[2], 5.0);
  const Vec3 p = *k.forward(q);
  EXPECT_DOUBLE_EQ(p[0], 10.0);
  EXPECT_DOUBLE_EQ(p[1], 3.0);
  Status s = k.check_segment({10, 10, 10}, {10, 250, 10});
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("Y250"), std::string::npos) << s.error().message;
}

}  // namespace
}  // namespace feedloop::planner

namespace feedloop::planner {
namespace {

TEST(PlannerConfig, ValidateRejectsBadValuesWithAMessage) {
  EXPECT_TRUE(test::cartesian_config().validate().ok());
  EXPECT_TRUE(test::delta_config().validate().ok());
  PlannerConfig c = test::cartesian_config();
  c.max_axis_accel_mm_s2[kY] = 0.0;
  Status s = c.validate();
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("accel"), std::string::npos);
  c = test::cartesian_config();
  c.sharp.alpha_a_deg = 30.0;  // above alpha_b
  EXPECT_FALSE(c.validate().ok());
  c = test::delta_config();
  c.delta.arm_length_mm = 100.0;  // shorter than the radius
  EXPECT_FALSE(c.validate().ok());
  // Klipper's conversion: scv 5 mm/s at 3000 mm/s^2
  EXPECT_NEAR(test::cartesian_config().junction_deviation(), 25.0 * (std::sqrt(2.0) - 1.0) / 3000.0, 1e-15);
}

}  // namespace
}  // namespace feedloop::planner
