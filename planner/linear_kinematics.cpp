// Cartesian and CoreXY kinematics (see linear_kinematics.hpp).
#include "planner/linear_kinematics.hpp"

#include <cstdio>  // snprintf

namespace feedloop::planner {

LinearKinematics::LinearKinematics(KinematicsKind kind, const Vec4& min_mm, const Vec4& max_mm)
    : kind_(kind), min_mm_(min_mm), max_mm_(max_mm) {
  if (kind == KinematicsKind::corexy) {
    m_ = {Vec3{1.0, 1.0, 0.0}, Vec3{1.0, -1.0, 0.0}, Vec3{0.0, 0.0, 1.0}};
  } else {
    m_ = {Vec3{1.0, 0.0, 0.0}, Vec3{0.0, 1.0, 0.0}, Vec3{0.0, 0.0, 1.0}};
  }
}

Joints LinearKinematics::inverse(const Vec3& p) const {
  Joints q{};
  for (int j = 0; j < 3; ++j) q[j] = m_[j][0] * p[0] + m_[j][1] * p[1] + m_[j][2] * p[2];
  return q;
}

Joints LinearKinematics::joint_velocity(const Vec3& /*p*/, const Vec3& v) const { return inverse(v); }

Result<Vec3> LinearKinematics::forward(const Joints& q) const {
  if (kind_ == KinematicsKind::corexy) {
    return Vec3{0.5 * (q[0] + q[1]), 0.5 * (q[0] - q[1]), q[2]};
  }
  return Vec3{q[0], q[1], q[2]};
}

Status LinearKinematics::check_point(const Vec3& p) const {
  static constexpr char kName[3] = {'X', 'Y', 'Z'};
  for (int i = 0; i < 3; ++i) {
    if (p[i] < min_mm_[i] - 1e-9 || p[i] > max_mm_[i] + 1e-9) {
      char buf[160];
      std::snprintf(buf, sizeof buf, "%c%.4g is outside the travel limits %c[%.4g, %.4g] mm",
                    kName[i], p[i], kName[i], min_mm_[i], max_mm_[i]);
      return Error{buf, {}};
    }
  }
  return {};
}

Status LinearKinematics::check_segment(const Vec3& a, const Vec3& b) const {
  // The travel box is convex: the segment is inside iff both ends are.
  if (Status s = check_point(a); !s) return s;
  return check_point(b);
}

}  // namespace feedloop::planner
