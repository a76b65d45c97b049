// Delta carriage and end-effector sub-models (see delta_submodels.hpp).
#include "model/delta_submodels.hpp"

#include <cmath>  // std::sqrt

namespace feedloop::model {

Complex carriage_mechanical(const DeltaParams& p, Complex s) {
  const double m = p.m_kg();  // Eq. 30
  return (p.c_n_s_m * s + p.k_n_m) / (m * s * s + (p.c_n_s_m + p.b_n_s_m) * s + p.k_n_m);  // Eq. 32
}

Complex carriage_electrical(const DeltaParams& p, Complex s) {
  return (p.d1_per_s * s + p.d0_per_s2) / (s * s + p.d2_per_s * s + p.d0_per_s2);  // Eq. 34
}

Complex carriage_position(const DeltaParams& p, Complex s) {
  return carriage_mechanical(p, s) * carriage_electrical(p, s);  // Eq. 31
}

Complex carriage_force(const DeltaParams& p, Complex s) {
  return -1.0 / (p.m_kg() * s * s + (p.c_n_s_m + p.b_n_s_m) * s + p.k_n_m);  // Eq. 44
}

TransferFunction carriage_electrical_tf(const DeltaParams& p) {
  return {{p.d1_per_s, p.d0_per_s2}, {1.0, p.d2_per_s, p.d0_per_s2}};
}

TransferFunction carriage_position_tf(const DeltaParams& p) {
  const double m = p.m_kg();
  // Eq. 33: (c/m s + wn^2)/(s^2 + 2 zeta wn s + wn^2) with 2 zeta wn = (c+b)/m, wn^2 = k/m (Eq. 35-36).
  const std::vector<double> num_m{p.c_n_s_m / m, p.k_n_m / m};
  const std::vector<double> den_m{1.0, (p.c_n_s_m + p.b_n_s_m) / m, p.k_n_m / m};
  const TransferFunction e = carriage_electrical_tf(p);
  return {polynomial_multiply(num_m, e.num), polynomial_multiply(den_m, e.den)};  // Eq. 42-43
}

StateSpace carriage_state_space(const DeltaParams& p) {
  const double m = p.m_kg(), c = p.c_n_s_m, cb = p.c_n_s_m + p.b_n_s_m, k = p.k_n_m;
  const double d0 = p.d0_per_s2, d1 = p.d1_per_s, d2 = p.d2_per_s, w = std::sqrt(d0);
  StateSpace s;
  s.A = Eigen::MatrixXd::Zero(4, 4);
  s.B = Eigen::MatrixXd::Zero(4, 2);
  // Electrical filter (Eq. 34): z1' = w z2, z2' = -w z1 - d2 z2 + w q_d.
  s.A(0, 1) = w;
  s.A(1, 0) = -w;
  s.A(1, 1) = -d2;
  s.B(1, 0) = w;
  // m q'' = k u + c u' - k q - (c+b) q' - F_q with u = z1 + (d1/w) z2,
  // u' = -d1 z1 + (w - d1 d2 / w) z2 + d1 q_d  (Eq. 32, 44).
  s.A(2, 3) = 1.0;
  s.A(3, 0) = (k - c * d1) / m;
  s.A(3, 1) = (k * d1 / w + c * (w - d1 * d2 / w)) / m;
  s.A(3, 2) = -k / m;
  s.A(3, 3) = -cb / m;
  s.B(3, 0) = c * d1 / m;
  s.B(3, 1) = -1.0 / m;
  s.C = Eigen::MatrixXd::Zero(1, 4);
  s.C(0, 2) = 1.0;
  s.D = Eigen::MatrixXd::Zero(1, 2);
  return s;
}

std::vector<double> eq68_characteristic_polynomial(const DeltaParams& p, double alpha, int axis_j,
                                                   Eq68Form form) {
  const double m = p.m_kg(), cb = p.c_n_s_m + p.b_n_s_m, k = p.k_n_m;
  const double m1 = p.m1_effective_kg(), m2 = p.m2_kg;
  const double bj[3] = {p.b_x_n_s_m, p.b_y_n_s_m, p.b_z_n_s_m};
  const double kj[3] = {p.k_x_n_m, p.k_y_n_m, p.k_z_n_m};
  const double b = bj[axis_j], kk = kj[axis_j];
  const double s2_cross = form == Eq68Form::AsPrinted ? alpha * cb * b : cb * b;
  return {(m + alpha * m1) * m2,                                   // Eq. 68, s^4
          (m + alpha * (m1 + m2)) * b + m2 * cb,                   // s^3
          (m + alpha * (m1 + m2)) * kk + m2 * k + s2_cross,        // s^2
          cb * kk + b * k,                                         // s^1
          kk * k};                                                 // s^0
}

Eigen::Vector3cd effector_dynamic_stiffness(const DeltaParams& p, Complex s) {
  const double m1 = p.m1_effective_kg();
  const double m2 = p.m2_kg;
  const double b[3] = {p.b_x_n_s_m, p.b_y_n_s_m, p.b_z_n_s_m};
  const double k[3] = {p.k_x_n_m, p.k_y_n_m, p.k_z_n_m};
  Eigen::Vector3cd w;
  for (int j = 0; j < 3; ++j) {
    if (m2 == 0.0) {
      w(j) = m1 * s * s;
    } else {
      const Complex bk = b[j] * s + k[j];
      w(j) = s * s * (m1 * m2 * s * s + (m1 + m2) * bk) / (m2 * s * s + bk);  // Eq. 67
    }
  }
  return w;
}

}  // namespace feedloop::model
