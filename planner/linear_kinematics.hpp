// Cartesian and CoreXY kinematics: joints are a constant linear map of (x, y, z).
// Cartesian: q = (x, y, z). CoreXY: q = (x + y, x - y, z) (Klipper kin_corexy.c convention).
// Reachability is the travel box of the config; the box is convex, so a segment is reachable iff
// both end points are.
#pragma once

#include "planner/kinematics.hpp"

namespace feedloop::planner {

class LinearKinematics final : public Kinematics {
 public:
  LinearKinematics(KinematicsKind kind, const Vec4& min_mm, const Vec4& max_mm);

  KinematicsKind kind() const override { return kind_; }
  Joints inverse(const Vec3& p) const override;
  Joints joint_velocity(const Vec3& p, const Vec3& v) const override;
  Result<Vec3> forward(const Joints& q) const override;
  Status check_point(const Vec3& p) const override;
  Status check_segment(const Vec3& a, const Vec3& b) const override;
  bool is_linear() const override { return true; }
  std::array<Vec3, 3> linear_map() const override { return m_; }

 private:
  KinematicsKind kind_;
  Vec4 min_mm_, max_mm_;
  std::array<Vec3, 3> m_{};
};

}  // namespace feedloop::planner
