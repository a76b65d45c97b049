// End-effector force distribution and transformation to the carriages (see delta_force.hpp).
#include "model/delta_force.hpp"

#include <cmath>    // std::cos, std::sin
#include <numbers>  // std::numbers::pi

namespace feedloop::model {

const char* to_string(ForceTransform f) {
  return f == ForceTransform::Paper ? "paper" : "virtual_work";
}

std::array<Eigen::Vector3d, 3> moment_arms_mm(const DeltaParams& p) {
  std::array<Eigen::Vector3d, 3> r;
  for (int i = 0; i < 3; ++i) {
    const double phi = p.geometry.tower_angle_deg[static_cast<size_t>(i)] * std::numbers::pi / 180.0;
    r[static_cast<size_t>(i)] = Eigen::Vector3d(p.D_e_mm * std::cos(phi) - p.delta_x_mm,
                                                p.D_e_mm * std::sin(phi) - p.delta_y_mm,
                                                -p.delta_z_mm);  // Eq. 20
  }
  return r;
}

Eigen::Matrix3d skew(const Eigen::Vector3d& r) {
  Eigen::Matrix3d s;
  s << 0.0, -r.z(), r.y(),  //
      r.z(), 0.0, -r.x(),   //
      -r.y(), r.x(), 0.0;
  return s;
}

Eigen::Matrix<double, 6, 9> equilibrium_matrix(const DeltaParams& p) {
  const auto r = moment_arms_mm(p);
  Eigen::Matrix<double, 6, 9> l;
  for (int i = 0; i < 3; ++i) {
    l.block<3, 3>(0, 3 * i) = Eigen::Matrix3d::Identity();     // Eq. 17: sum of forces
    l.block<3, 3>(3, 3 * i) = skew(r[static_cast<size_t>(i)]);  // Eq. 19: sum of moments
  }
  return l;
}

std::array<Eigen::Matrix3d, 3> force_distribution(const DeltaParams& p) {
  const Eigen::Matrix<double, 6, 9> l = equilibrium_matrix(p);
  const Eigen::Matrix<double, 6, 6> llt = l * l.transpose();
  // Eq. 22: L^+ = L^T (L L^T)^-1; only its first three columns act on u = [W X; 0].
  const Eigen::Matrix<double, 9, 6> lpinv = l.transpose() * llt.inverse();
  std::array<Eigen::Matrix3d, 3> pm;
  for (int i = 0; i < 3; ++i) pm[static_cast<size_t>(i)] = lpinv.block<3, 3>(3 * i, 0);  // Eq. 23
  return pm;
}

Eigen::Matrix3d force_transform(const DeltaParams& p, const Eigen::Matrix3d& jbar, ForceTransform form) {
  if (form == ForceTransform::VirtualWork) return jbar.transpose();  // tau = Jbar^T W X
  const auto pm = force_distribution(p);
  Eigen::Matrix3d t;
  for (int i = 0; i < 3; ++i)
    t.row(i) = jbar.col(i).transpose() * pm[static_cast<size_t>(i)];  // Eq. 25 / 69
  return t;
}

}  // namespace feedloop::model
