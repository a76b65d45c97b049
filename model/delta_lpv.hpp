// The delta printer's linear parameter-varying model by receptance coupling
// (delta-lpv-receptance-coupling.txt, Eq. 27-29): at a frozen position X-bar,
//   q(s) = G(s) q_d(s),  G(s) = [I - G_Fq(s) T W(s) Jbar]^-1 G_qd(s)                 (Eq. 29)
// with G_qd, G_Fq the carriage sub-model (Eq. 31, 44; scalars times I), W(s) the two-mass
// end-effector (Eq. 61/67), Jbar the Jacobian at X-bar (Eq. 12) and T the force transformation:
// the paper's [Jbar_i^T P_i] (Eq. 25/69, default) or the virtual-work Jbar^T (delta_force.hpp).
// Input: commanded carriage positions q_d (A, B, C); output: actual carriage positions q.
// Both are positions, so G(0) = I.
#pragma once

#include <Eigen/Dense>

#include "core/result.hpp"
#include "model/delta_force.hpp"
#include "model/delta_params.hpp"
#include "model/frequency_grid.hpp"
#include "model/frf_set.hpp"
#include "model/lti.hpp"

namespace feedloop::model {

// Everything that depends on the position, computed once per position.
struct DeltaOperatingPoint {
  Eigen::Vector3d pos_mm;     // X-bar (nozzle)
  Eigen::Vector3d q_mm;       // q-bar
  Eigen::Matrix3d jbar;       // Eq. 12 at X-bar
  Eigen::Matrix3d transform;  // T: F_q = T W(s) X
  ForceTransform form = ForceTransform::Paper;
};

class DeltaLpvModel {
 public:
  // Validates the parameters.
  static Result<DeltaLpvModel> create(const DeltaParams& params, ForceTransform form = ForceTransform::Paper);

  const DeltaParams& params() const { return params_; }
  ForceTransform form() const { return form_; }

  // Error when the position is out of reach or singular.
  Result<DeltaOperatingPoint> at(const Eigen::Vector3d& pos_mm) const;

  // Eq. 29 at complex frequency s (rad/s).
  Eigen::Matrix3cd frf(const DeltaOperatingPoint& op, Complex s) const;
  Eigen::Matrix3cd frf_hz(const DeltaOperatingPoint& op, double f_hz) const;
  FrfSet frf(const DeltaOperatingPoint& op, const FrequencyGrid& grid) const;
  Result<FrfSet> frf(const Eigen::Vector3d& pos_mm, const FrequencyGrid& grid) const;

  // Low-frequency effective end-effector mass on the carriages: F_q ~ M s^2 q as s -> 0,
  // M = (m1 + m2) T Jbar (kg). For a centred symmetric effector its row sums are m_e/9 (paper)
  // or m_e/3 (virtual work).
  Eigen::Matrix3d effective_mass_kg(const DeltaOperatingPoint& op) const;

  // A state-space realisation of Eq. 29 at the operating point (SI, positions in m):
  // states [z1 (3), z2 (3), q (3), q' (3), X2 (3), X2' (3)] where z1 = d0 xi, z2 = sqrt(d0) xi'
  // are the electrical filter's states in position units (u = d0 xi + d1 xi', Eq. 34),
  // q the carriage positions and X2 the extruder-motor mass
  // (dropped when m2 = 0: 12 states). Inputs q_d (3), outputs q (3). Its frequency response equals
  // frf() and its static gain is I.
  Result<StateSpace> state_space(const DeltaOperatingPoint& op) const;

 private:
  DeltaLpvModel(const DeltaParams& p, ForceTransform f) : params_(p), form_(f) {}
  DeltaParams params_;
  ForceTransform form_;
};

}  // namespace feedloop::model
