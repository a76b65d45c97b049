// Delta LPV model, Eq. 27-29, and its state-space realisation (see delta_lpv.hpp).
#include "model/delta_lpv.hpp"

#include <cmath>    // std::sqrt
#include <numbers>  // std::numbers::pi

#include "model/delta_kinematics.hpp"
#include "model/delta_submodels.hpp"

namespace feedloop::model {

Result<DeltaLpvModel> DeltaLpvModel::create(const DeltaParams& params, ForceTransform form) {
  if (Status st = validate(params); !st) return st.error();
  return DeltaLpvModel(params, form);
}

Result<DeltaOperatingPoint> DeltaLpvModel::at(const Eigen::Vector3d& pos_mm) const {
  auto q = inverse_kinematics(params_.geometry, pos_mm);
  if (!q) return q.error();
  auto j = jacobian(params_.geometry, pos_mm);
  if (!j) return j.error();
  DeltaOperatingPoint op;
  op.pos_mm = pos_mm;
  op.q_mm = *q;
  op.jbar = *j;
  op.transform = force_transform(params_, op.jbar, form_);
  op.form = form_;
  return op;
}

Eigen::Matrix3cd DeltaLpvModel::frf(const DeltaOperatingPoint& op, Complex s) const {
  const Complex g_qd = carriage_position(params_, s);  // Eq. 31
  const Complex g_fq = carriage_force(params_, s);     // Eq. 44
  const Eigen::Vector3cd w = effector_dynamic_stiffness(params_, s);  // Eq. 67
  // Eq. 29: [I - G_Fq T W Jbar]^-1 G_qd.
  const Eigen::Matrix3cd coupling = op.transform.cast<Complex>() * w.asDiagonal() * op.jbar.cast<Complex>();
  const Eigen::Matrix3cd lhs = Eigen::Matrix3cd::Identity() - g_fq * coupling;
  return lhs.partialPivLu().solve(g_qd * Eigen::Matrix3cd::Identity());
}

Eigen::Matrix3cd DeltaLpvModel::frf_hz(const DeltaOperatingPoint& op, double f_hz) const {
  return frf(op, Complex(0.0, 2.0 * std::numbers::pi * f_hz));
}

FrfSet DeltaLpvModel::frf(const DeltaOperatingPoint& op, const FrequencyGrid& grid) const {
  FrfSet set;
  set.freq_hz = grid.points_hz();
  set.h.reserve(set.freq_hz.size());
  for (double f : set.freq_hz) set.h.push_back(frf_hz(op, f));
  return set;
}

Result<FrfSet> DeltaLpvModel::frf(const Eigen::Vector3d& pos_mm, const FrequencyGrid& grid) const {
  if (Status st = grid.validate(); !st) return st.error();
  auto op = at(pos_mm);
  if (!op) return op.error();
  return frf(*op, grid);
}

Eigen::Matrix3d DeltaLpvModel::effective_mass_kg(const DeltaOperatingPoint& op) const {
  return (params_.m1_effective_kg() + params_.m2_kg) * op.transform * op.jbar;
}

Result<StateSpace> DeltaLpvModel::state_space(const DeltaOperatingPoint& op) const {
  const DeltaParams& p = params_;
  const bool two_mass = p.m2_kg > 0.0;
  const int n = two_mass ? 18 : 12;
  const double m = p.m_kg(), c = p.c_n_s_m, cb = p.c_n_s_m + p.b_n_s_m, k = p.k_n_m;
  const double d0 = p.d0_per_s2, d1 = p.d1_per_s, d2 = p.d2_per_s;
  const double m1 = p.m1_effective_kg();
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  const Eigen::Matrix3d T = op.transform;
  const Eigen::Matrix3d J = op.jbar;
  const Eigen::Matrix3d Bj = Eigen::Vector3d(p.b_x_n_s_m, p.b_y_n_s_m, p.b_z_n_s_m).asDiagonal();
  const Eigen::Matrix3d Kj = Eigen::Vector3d(p.k_x_n_m, p.k_y_n_m, p.k_z_n_m).asDiagonal();

  // (m I + m1 T Jbar) q'' = k u + c u' - k q - (c+b) q' - T W-part (Eq. 1, 44, 50-52 with X = Jbar q).
  const Eigen::Matrix3d mq = m * I + m1 * T * J;
  Eigen::FullPivLU<Eigen::Matrix3d> lu(mq);
  if (!lu.isInvertible()) return Error{"delta mass matrix is singular at this position", {}};
  const Eigen::Matrix3d mq_inv = lu.inverse();

  enum : int { kXi = 0, kXiDot = 3, kQ = 6, kQDot = 9, kX2 = 12, kX2Dot = 15 };
  StateSpace s;
  s.A = Eigen::MatrixXd::Zero(n, n);
  s.B = Eigen::MatrixXd::Zero(n, 3);
  s.C = Eigen::MatrixXd::Zero(3, n);
  s.D = Eigen::MatrixXd::Zero(3, 3);

  // Electrical filter (Eq. 34) in states scaled to position units (keeps A well conditioned):
  // z1 = d0 xi, z2 = sqrt(d0) xi' for xi'' = -d0 xi - d2 xi' + q_d, u = d0 xi + d1 xi':
  //   z1' = w z2,  z2' = -w z1 - d2 z2 + w q_d  (w = sqrt(d0)),
  //   u = z1 + (d1/w) z2,  u' = -d1 z1 + (w - d1 d2/w) z2 + d1 q_d.
  const double w = std::sqrt(d0);
  s.A.block(kXi, kXiDot, 3, 3) = w * I;
  s.A.block(kXiDot, kXi, 3, 3) = -w * I;
  s.A.block(kXiDot, kXiDot, 3, 3) = -d2 * I;
  s.B.block(kXiDot, 0, 3, 3) = w * I;

  // Carriage: q'' = mq^-1 [k u + c u' - k q - (c+b) q' - T Kj Jbar q - T Bj Jbar q' + T Kj X2 + T Bj X2'].
  s.A.block(kQ, kQDot, 3, 3) = I;
  s.A.block(kQDot, kXi, 3, 3) = mq_inv * ((k - c * d1) * I);
  s.A.block(kQDot, kXiDot, 3, 3) = mq_inv * ((k * d1 / w + c * (w - d1 * d2 / w)) * I);
  s.B.block(kQDot, 0, 3, 3) = mq_inv * (c * d1 * I);
  if (two_mass) {
    s.A.block(kQDot, kQ, 3, 3) = mq_inv * (-k * I - T * Kj * J);
    s.A.block(kQDot, kQDot, 3, 3) = mq_inv * (-cb * I - T * Bj * J);
    s.A.block(kQDot, kX2, 3, 3) = mq_inv * (T * Kj);
    s.A.block(kQDot, kX2Dot, 3, 3) = mq_inv * (T * Bj);
    // Extruder motor mass (Eq. 53-55): m2 X2'' = Bj (Jbar q' - X2') + Kj (Jbar q - X2).
    s.A.block(kX2, kX2Dot, 3, 3) = I;
    s.A.block(kX2Dot, kQ, 3, 3) = Kj * J / p.m2_kg;
    s.A.block(kX2Dot, kQDot, 3, 3) = Bj * J / p.m2_kg;
    s.A.block(kX2Dot, kX2, 3, 3) = -Kj / p.m2_kg;
    s.A.block(kX2Dot, kX2Dot, 3, 3) = -Bj / p.m2_kg;
  } else {
    s.A.block(kQDot, kQ, 3, 3) = mq_inv * (-k * I);
    s.A.block(kQDot, kQDot, 3, 3) = mq_inv * (-cb * I);
  }
  s.C.block(0, kQ, 3, 3) = I;
  return s;
}

}  // namespace feedloop::model
