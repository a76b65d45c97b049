// Delta kinematics (Eq. 3-13) on the canonical geometry of DESIGN.md: inverse/forward round trip,
// the Jacobian of Eq. 12 against finite differences of the kinematics, and reachability errors.
#include <gtest/gtest.h>

#include "model/delta_kinematics.hpp"

namespace fm = feedloop::model;

namespace {

const Eigen::Vector3d kValidation[] = {
    {0, 0, 30}, {-80, 0, 30}, {40, -69, 30}, {40, 69, 30}, {55, 20, 120}, {-30, -95, 5}};

}  // namespace

TEST(DeltaKinematics, CanonicalGeometry) {
  const fm::DeltaGeometry g;
  EXPECT_NEAR(g.tower_xy_mm(0).x(), 145.0, 1e-12);
  EXPECT_NEAR(g.tower_xy_mm(0).y(), 0.0, 1e-12);
  EXPECT_NEAR(g.tower_xy_mm(1).x(), -72.5, 1e-12);
  EXPECT_NEAR(g.tower_xy_mm(1).y(), 125.574, 1e-3);
  EXPECT_NEAR(g.tower_xy_mm(2).y(), -125.574, 1e-3);
}

TEST(DeltaKinematics, InverseAtCentre) {
  const fm::DeltaGeometry g;
  auto q = fm::inverse_kinematics(g, {0, 0, 30});
  ASSERT_TRUE(q.ok());
  const double h = std::sqrt(300.0 * 300.0 - 145.0 * 145.0);  // 262.63 mm
  for (int i = 0; i < 3; ++i) EXPECT_NEAR((*q)(i), 30.0 + 20.0 + h, 1e-9);
}

TEST(DeltaKinematics, ForwardInvertsInverse) {
  const fm::DeltaGeometry g;
  for (const auto& x : kValidation) {
    auto q = fm::inverse_kinematics(g, x);
    ASSERT_TRUE(q.ok());
    auto back = fm::forward_kinematics(g, *q);
    ASSERT_TRUE(back.ok()) << back.error().message;
    EXPECT_LT((*back - x).norm(), 1e-8) << x.transpose();
  }
}

TEST(DeltaKinematics, JacobianMatchesFiniteDifferences) {
  const fm::DeltaGeometry g;
  const double h = 1e-4;  // mm
  for (const auto& x : kValidation) {
    auto j = fm::jacobian(g, x);
    ASSERT_TRUE(j.ok());
    auto q = fm::inverse_kinematics(g, x);
    ASSERT_TRUE(q.ok());
    // dX/dq by central differences of the forward kinematics.
    Eigen::Matrix3d fd_fk;
    for (int i = 0; i < 3; ++i) {
      Eigen::Vector3d dq = Eigen::Vector3d::Zero();
      dq(i) = h;
      auto xp = fm::forward_kinematics(g, *q + dq);
      auto xm = fm::forward_kinematics(g, *q - dq);
      ASSERT_TRUE(xp.ok() && xm.ok());
      fd_fk.col(i) = (*xp - *xm) / (2 * h);
    }
    EXPECT_LT((*j - fd_fk).cwiseAbs().maxCoeff(), 1e-6) << "at " << x.transpose() << "\nJ=\n"
                                                         << *j << "\nFD=\n" << fd_fk;
    // dq/dX by central differences of the inverse kinematics: J * dq/dX = I.
    Eigen::Matrix3d fd_ik;
    for (int k = 0; k < 3; ++k) {
      Eigen::Vector3d dx = Eigen::Vector3d::Zero();
      dx(k) = h;
      fd_ik.col(k) = (*fm::inverse_kinematics(g, x + dx) - *fm::inverse_kinematics(g, x - dx)) / (2 * h);
    }
    EXPECT_LT((*j * fd_ik - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-6);
  }
}

TEST(DeltaKinematics, CentreJacobianSharesVerticalMotionInThirds) {
  auto j = fm::jacobian(fm::DeltaGeometry{}, {0, 0, 30});
  ASSERT_TRUE(j.ok());
  for (int i = 0; i < 3; ++i) EXPECT_NEAR((*j)(2, i), 1.0 / 3.0, 1e-12);
  EXPECT_LT((*j * Eigen::Vector3d::Ones() - Eigen::Vector3d(0, 0, 1)).norm(), 1e-12);
}

TEST(DeltaKinematics, OutOfReachIsAnError) {
  const fm::DeltaGeometry g;
  auto q = fm::inverse_kinematics(g, {-200, 0, 30});  // 345 mm from tower A > L
  ASSERT_FALSE(q.ok());
  EXPECT_NE(q.error().message.find("out of reach of arm A"), std::string::npos) << q.error().message;
  EXPECT_FALSE(fm::jacobian(g, {-200, 0, 30}).ok());
  EXPECT_FALSE(fm::inverse_kinematics(g, {std::nan(""), 0, 0}).ok());
}
