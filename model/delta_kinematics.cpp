// Delta kinematics and Jacobian (see delta_kinematics.hpp).
#include "model/delta_kinematics.hpp"

#include <cmath>    // std::cos, std::sin, std::sqrt
#include <cstdio>   // std::snprintf
#include <numbers>  // std::numbers::pi
#include <string>

namespace feedloop::model {
namespace {

std::string fmt_pos(const Eigen::Vector3d& v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.6g, %.6g, %.6g)", v.x(), v.y(), v.z());
  return buf;
}

// Rows s_i^T of Eq. 11 at (X, q).
Eigen::Matrix3d s_rows(const DeltaGeometry& g, const Eigen::Vector3d& x, const Eigen::Vector3d& q) {
  Eigen::Matrix3d s;
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector2d t = g.tower_xy_mm(i);
    s.row(i) << x.x() - t.x(), x.y() - t.y(), x.z() + g.nozzle_offset_mm - q(i);  // Eq. 7
  }
  return s;
}

}  // namespace

Eigen::Vector2d DeltaGeometry::tower_xy_mm(int i) const {
  const double a = tower_angle_deg[static_cast<size_t>(i)] * std::numbers::pi / 180.0;
  return {radius_mm * std::cos(a), radius_mm * std::sin(a)};
}

Status validate(const DeltaGeometry& g) {
  if (!(g.radius_mm > 0.0) || !(g.arm_length_mm > g.radius_mm) || !std::isfinite(g.arm_length_mm))
    return Error{"delta geometry needs 0 < radius_mm < arm_length_mm", {}};
  if (!std::isfinite(g.nozzle_offset_mm)) return Error{"delta nozzle_offset_mm is not finite", {}};
  for (double a : g.tower_angle_deg)
    if (!std::isfinite(a)) return Error{"delta tower angle is not finite", {}};
  return {};
}

Result<Eigen::Vector3d> inverse_kinematics(const DeltaGeometry& g, const Eigen::Vector3d& pos_mm) {
  if (!pos_mm.allFinite()) return Error{"delta position is not finite", {}};
  Eigen::Vector3d q;
  const double l2 = g.arm_length_mm * g.arm_length_mm;
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector2d d = pos_mm.head<2>() - g.tower_xy_mm(i);
    const double h2 = l2 - d.squaredNorm();
    // Require a margin: at h -> 0 the arm is horizontal and the Jacobian singular.
    if (h2 <= 1e-6 * l2)
      return Error{"delta position " + fmt_pos(pos_mm) + " mm is out of reach of arm " +
                       std::string(1, static_cast<char>('A' + i)),
                   {}};
    q(i) = pos_mm.z() + g.nozzle_offset_mm + std::sqrt(h2);  // Eq. 3-5
  }
  return q;
}

Result<Eigen::Vector3d> forward_kinematics(const DeltaGeometry& g, const Eigen::Vector3d& q_mm) {
  if (!q_mm.allFinite()) return Error{"delta carriage positions are not finite", {}};
  const double l = g.arm_length_mm;
  // Start below the mean carriage height at the centre.
  Eigen::Vector3d x(0.0, 0.0, q_mm.mean() - g.nozzle_offset_mm -
                                   std::sqrt(l * l - g.radius_mm * g.radius_mm));
  for (int it = 0; it < 50; ++it) {
    const Eigen::Matrix3d s = s_rows(g, x, q_mm);
    Eigen::Vector3d f;
    for (int i = 0; i < 3; ++i) f(i) = s.row(i).squaredNorm() - l * l;  // Eq. 6
    if (f.cwiseAbs().maxCoeff() < 1e-13 * l * l) break;
    Eigen::FullPivLU<Eigen::Matrix3d> lu(2.0 * s);
    if (!lu.isInvertible()) return Error{"delta forward kinematics hit a singular configuration", {}};
    x -= lu.solve(f);
  }
  const Eigen::Matrix3d s = s_rows(g, x, q_mm);
  for (int i = 0; i < 3; ++i) {
    if (std::abs(s.row(i).squaredNorm() - l * l) > 1e-6 * l * l || s(i, 2) >= 0.0)
      return Error{"delta carriage positions " + fmt_pos(q_mm) + " mm have no valid effector pose", {}};
  }
  return x;
}

Result<Eigen::Matrix3d> jacobian(const DeltaGeometry& g, const Eigen::Vector3d& pos_mm) {
  auto q = inverse_kinematics(g, pos_mm);
  if (!q) return q.error();
  const Eigen::Matrix3d s = s_rows(g, pos_mm, *q);
  const Eigen::Vector3d p(0.0, 0.0, -1.0);  // Eq. 10
  Eigen::FullPivLU<Eigen::Matrix3d> lu(s);
  if (!lu.isInvertible())
    return Error{"delta Jacobian is singular at " + fmt_pos(pos_mm) + " mm", {}};
  const Eigen::Vector3d sp = s * p;  // s_i^T p
  return Eigen::Matrix3d(-lu.solve(Eigen::Matrix3d(sp.asDiagonal())));  // Eq. 12
}

}  // namespace feedloop::model
