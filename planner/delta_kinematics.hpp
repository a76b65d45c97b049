// Linear delta kinematics with the canonical geometry (DESIGN.md contract) and the delta paper's
// notation (delta-lpv-receptance-coupling, Sect. III-A):
//   towers i in {A, B, C} at angles 0/120/240 deg on radius R, (i_x, i_y) = R (cos, sin);
//   constraint (Eq. 3-6):  s_i^T s_i = L^2,  s_i = [x - i_x, y - i_y, z + H_ez - q_i]^T  (Eq. 7)
//   => inverse kinematics q_i = z + H_ez + sqrt(L^2 - (x - i_x)^2 - (y - i_y)^2)  (carriage above)
//   Jacobian (Eq. 12): Xdot = J qdot,  J = -[s_A s_B s_C]^-T diag(s_i^T p),  p = [0 0 -1]^T (Eq. 10)
//   and its inverse row by row from Eq. 9: qdot_i = -(s_i^T Xdot) / (s_i^T p).
// Workspace: disk of print_radius, z range of the config, arm angle below max_arm_angle_deg and
// carriages inside [carriage_min_mm, carriage_max_mm].
#pragma once

#include <Eigen/Dense>

#include "planner/kinematics.hpp"

namespace feedloop::planner {

class DeltaKinematics final : public Kinematics {
 public:
  DeltaKinematics(const DeltaGeometry& geometry, double min_z_mm, double max_z_mm);

  KinematicsKind kind() const override { return KinematicsKind::delta; }
  Joints inverse(const Vec3& p) const override;
  Joints joint_velocity(const Vec3& p, const Vec3& v) const override;
  void inverse_with_velocity(const Vec3& p, const Vec3& v, Joints& q, Joints& qd) const override;
  Result<Vec3> forward(const Joints& q) const override;
  Status check_point(const Vec3& p) const override;
  // Samples the segment every geometry.check_step_mm (and both ends). The disk, the arm-angle
  // disks and the z range are convex, so for them the ends suffice; the carriage travel is not
  // (q_i is not monotonic along a line), hence the samples.
  Status check_segment(const Vec3& a, const Vec3& b) const override;
  bool is_linear() const override { return false; }

  // Eq. 12 at position p (p must be reachable).
  Eigen::Matrix3d jacobian(const Vec3& p) const;
  // Tower (carriage column) position (i_x, i_y).
  std::array<double, 2> tower_xy(int i) const { return tower_[i]; }
  const DeltaGeometry& geometry() const { return g_; }

 private:
  DeltaGeometry g_;
  double min_z_mm_, max_z_mm_;
  std::array<std::array<double, 2>, 3> tower_{};
  double max_d2_mm2_;  // (L sin(max arm angle))^2
};

}  // namespace feedloop::planner
