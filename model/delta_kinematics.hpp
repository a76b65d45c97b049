// Delta printer kinematics and the kinematic Jacobian (delta-lpv-receptance-coupling.txt,
// Sect. III-A, Eq. 3-13).
//
// Canonical geometry (DESIGN.md, contract): carriage A at 0 deg (+x), B at 120 deg, C at 240 deg on
// an effective radius R = 145 mm (tower radius minus the effector's joint offset); forearm length
// L = 300 mm; nozzle offset H_ez = 20 mm (the nozzle tip is H_ez below the plane of the effector
// joints). X = [x, y, z] is the nozzle position, q = [q_A, q_B, q_C] the carriage heights (mm).
//   s_i = [x - i_x, y - i_y, z + H_ez - q_i],  s_i^T s_i = L^2                       (Eq. 6-7)
//   q_i = z + H_ez + sqrt(L^2 - (x - i_x)^2 - (y - i_y)^2)   (carriage above the effector)
//   X' = J q',  J = -[s_A^T; s_B^T; s_C^T]^-1 diag(s_i^T p),  p = [0, 0, -1]^T        (Eq. 2, 12)
// At rest (q' = 0) the linearised Jacobian of Remark III(b) is J evaluated at X-bar (the J' q' term
// of Eq. 13 vanishes).
#pragma once

#include <array>

#include <Eigen/Dense>

#include "core/result.hpp"

namespace feedloop::model {

struct DeltaGeometry {
  double radius_mm = 145.0;        // R, effective carriage radius
  double arm_length_mm = 300.0;    // L
  double nozzle_offset_mm = 20.0;  // H_ez
  std::array<double, 3> tower_angle_deg = {0.0, 120.0, 240.0};  // phi_A, phi_B, phi_C

  // (i_x, i_y) of carriage i in mm.
  Eigen::Vector2d tower_xy_mm(int i) const;
};

Status validate(const DeltaGeometry& g);

// q from X (Eq. 3-5). Error when X is out of reach of an arm (horizontal distance >= L).
Result<Eigen::Vector3d> inverse_kinematics(const DeltaGeometry& g, const Eigen::Vector3d& pos_mm);

// X from q by Newton's method on Eq. 3-5 (the solution with the effector below the carriages).
Result<Eigen::Vector3d> forward_kinematics(const DeltaGeometry& g, const Eigen::Vector3d& q_mm);

// J of Eq. 12 at X (dimensionless, X' = J q'). Error when out of reach or singular.
Result<Eigen::Matrix3d> jacobian(const DeltaGeometry& g, const Eigen::Vector3d& pos_mm);

}  // namespace feedloop::model
