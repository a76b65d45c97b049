// Delta kinematics (see delta_kinematics.hpp for the equations).
#include "planner/delta_kinematics.hpp"

#include <algorithm>  // std::max
#include <cmath>      // sqrt, cos, sin, ceil
#include <cstdio>     // snprintf

namespace feedloop::planner {

namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr char kTower[3] = {'A', 'B', 'C'};
}  // namespace

DeltaKinematics::DeltaKinematics(const DeltaGeometry& geometry, double min_z_mm, double max_z_mm)
    : g_(geometry), min_z_mm_(min_z_mm), max_z_mm_(max_z_mm) {
  for (int i = 0; i < 3; ++i) {
    const double a = g_.tower_angle_deg[i] * kPi / 180.0;
    tower_[i] = {g_.radius_mm * std::cos(a), g_.radius_mm * std::sin(a)};
  }
  const double r = g_.arm_length_mm * std::sin(g_.max_arm_angle_deg * kPi / 180.0);
  max_d2_mm2_ = r * r;
}

Joints DeltaKinematics::inverse(const Vec3& p) const {
  Joints q{};
  const double l2 = g_.arm_length_mm * g_.arm_length_mm;
  for (int i = 0; i < 3; ++i) {
    const double dx = p[0] - tower_[i][0], dy = p[1] - tower_[i][1];
    q[i] = p[2] + g_.nozzle_offset_mm + std::sqrt(l2 - dx * dx - dy * dy);  // Eq. 3-5 solved for q_i
  }
  return q;
}

Joints DeltaKinematics::joint_velocity(const Vec3& p, const Vec3& v) const {
  Joints q, qd;
  inverse_with_velocity(p, v, q, qd);
  return qd;
}

void DeltaKinematics::inverse_with_velocity(const Vec3& p, const Vec3& v, Joints& q, Joints& qd) const {
  const double l2 = g_.arm_length_mm * g_.arm_length_mm;
  for (int i = 0; i < 3; ++i) {
    const double sx = p[0] - tower_[i][0], sy = p[1] - tower_[i][1];
    const double root = std::sqrt(l2 - sx * sx - sy * sy);
    q[i] = p[2] + g_.nozzle_offset_mm + root;
    const double sz = -root;  // Eq. 7: z + H_ez - q_i
    // Eq. 9-10: s_i^T (Xdot + p qdot_i) = 0 with p = [0 0 -1] => qdot_i = s_i^T Xdot / s_iz
    qd[i] = (sx * v[0] + sy * v[1] + sz * v[2]) / sz;
  }
}

Eigen::Matrix3d DeltaKinematics::jacobian(const Vec3& p) const {
  const Joints q = inverse(p);
  Eigen::Matrix3d s;      // rows s_i^T (Eq. 11)
  Eigen::Matrix3d d = Eigen::Matrix3d::Zero();  // diag(s_i^T p)
  const Eigen::Vector3d pv(0.0, 0.0, -1.0);     // p of Eq. 10
  for (int i = 0; i < 3; ++i) {
    s.row(i) << p[0] - tower_[i][0], p[1] - tower_[i][1], p[2] + g_.nozzle_offset_mm - q[i];
    d(i, i) = s.row(i).dot(pv);
  }
  return -s.inverse() * d;  // Eq. 12
}

Result<Vec3> DeltaKinematics::forward(const Joints& q) const {
  // Trilateration: |X - c_i| = L with sphere centres c_i = (i_x, i_y, q_i - H_ez) (Eq. 7).
  std::array<Vec3, 3> c{};
  for (int i = 0; i < 3; ++i) c[i] = {tower_[i][0], tower_[i][1], q[i] - g_.nozzle_offset_mm};
  auto n2 = [](const Vec3& v) { return v[0] * v[0] + v[1] * v[1] + v[2] * v[2]; };
  // Subtracting sphere 0 from spheres 1, 2: 2 (c_i - c_0) . X = |c_i|^2 - |c_0|^2.
  double a[2], b[2], cz[2], d[2];
  for (int k = 0; k < 2; ++k) {
    const Vec3& ci = c[k + 1];
    a[k] = 2.0 * (ci[0] - c[0][0]);
    b[k] = 2.0 * (ci[1] - c[0][1]);
    cz[k] = 2.0 * (ci[2] - c[0][2]);
    d[k] = n2(ci) - n2(c[0]);
  }
  const double det = a[0] * b[1] - a[1] * b[0];
  if (std::abs(det) < 1e-12) return Error{"delta forward kinematics: towers are collinear", {}};
  // x = ex + fx z, y = ey + fy z
  const double ex = (d[0] * b[1] - d[1] * b[0]) / det, fx = (-cz[0] * b[1] + cz[1] * b[0]) / det;
  const double ey = (a[0] * d[1] - a[1] * d[0]) / det, fy = (-a[0] * cz[1] + a[1] * cz[0]) / det;
  const double gx = ex - c[0][0], gy = ey - c[0][1];
  const double qa = fx * fx + fy * fy + 1.0;
  const double qb = 2.0 * (gx * fx + gy * fy - c[0][2]);
  const double qc = gx * gx + gy * gy + c[0][2] * c[0][2] - g_.arm_length_mm * g_.arm_length_mm;
  const double disc = qb * qb - 4.0 * qa * qc;
  if (disc < 0.0) return Error{"delta forward kinematics: carriage positions are inconsistent (arms cannot meet)", {}};
  const double z = (-qb - std::sqrt(disc)) / (2.0 * qa);  // the solution below the carriages
  return Vec3{ex + fx * z, ey + fy * z, z};
}

Status DeltaKinematics::check_point(const Vec3& p) const {
  char buf[200];
  const double r2 = p[0] * p[0] + p[1] * p[1];
  if (r2 > g_.print_radius_mm * g_.print_radius_mm + 1e-9) {
    std::snprintf(buf, sizeof buf, "X%.4g Y%.4g is outside the delta print radius (%.4g mm > %.4g mm)",
                  p[0], p[1], std::sqrt(r2), g_.print_radius_mm);
    return Error{buf, {}};
  }
  if (p[2] < min_z_mm_ - 1e-9 || p[2] > max_z_mm_ + 1e-9) {
    std::snprintf(buf, sizeof buf, "Z%.4g is outside the travel limits Z[%.4g, %.4g] mm", p[2], min_z_mm_, max_z_mm_);
    return Error{buf, {}};
  }
  const double l2 = g_.arm_length_mm * g_.arm_length_mm;
  for (int i = 0; i < 3; ++i) {
    const double dx = p[0] - tower_[i][0], dy = p[1] - tower_[i][1];
    const double d2 = dx * dx + dy * dy;
    if (d2 > max_d2_mm2_) {
      std::snprintf(buf, sizeof buf,
                    "X%.4g Y%.4g Z%.4g is unreachable: arm %c would be %.1f deg from vertical (max %.1f)",
                    p[0], p[1], p[2], kTower[i], std::asin(std::min(1.0, std::sqrt(d2) / g_.arm_length_mm)) * 180.0 / kPi,
                    g_.max_arm_angle_deg);
      return Error{buf, {}};
    }
    const double q = p[2] + g_.nozzle_offset_mm + std::sqrt(l2 - d2);
    if (q < g_.carriage_min_mm - 1e-9 || q > g_.carriage_max_mm + 1e-9) {
      std::snprintf(buf, sizeof buf,
                    "X%.4g Y%.4g Z%.4g is unreachable: carriage %c at %.4g mm outside its travel [%.4g, %.4g] mm",
                    p[0], p[1], p[2], kTower[i], q, g_.carriage_min_mm, g_.carriage_max_mm);
      return Error{buf, {}};
    }
  }
  return {};
}

Status DeltaKinematics::check_segment(const Vec3& a, const Vec3& b) const {
  const double dx = b[0] - a[0], dy = b[1] - a[1], dz = b[2] - a[2];
  const double len = std::sqrt(dx * dx + dy * dy + dz * dz);
  const int n = std::max(1, static_cast<int>(std::ceil(len / std::max(g_.check_step_mm, 1e-3))));
  for (int k = 0; k <= n; ++k) {
    const double f = static_cast<double>(k) / n;
    if (Status s = check_point({a[0] + f * dx, a[1] + f * dy, a[2] + f * dz}); !s) return s;
  }
  return {};
}

}  // namespace feedloop::planner
