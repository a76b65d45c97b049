// Thesis gantry axis model (see gantry_axis.hpp).
#include "model/gantry_axis.hpp"

#include <cmath>    // std::isfinite
#include <numbers>  // std::numbers::pi

namespace feedloop::model {

GantryAxisParams thesis_x_axis() { return GantryAxisParams{}; }

GantryAxisParams thesis_y_axis() {
  GantryAxisParams p;
  p.m1_kg = 0.130;   // Table 3 (same motor)
  p.m2_kg = 1.07;    // Table 2: the whole X carriage
  p.k1_n_m = 392e3;  // Table 4
  p.k2_n_m = 19.7e3;
  p.c1_n_s_m = 411.0;
  p.c2_n_s_m = 71.5;
  return p;
}

Status validate(const GantryAxisParams& p) {
  const double all[] = {p.m1_kg, p.m2_kg, p.k1_n_m, p.k2_n_m, p.c1_n_s_m, p.c2_n_s_m, p.e_frac};
  for (double v : all)
    if (!std::isfinite(v)) return Error{"gantry axis parameter is not finite", {}};
  if (p.m1_kg <= 0.0 || p.m2_kg <= 0.0) return Error{"gantry axis masses m1_kg, m2_kg must be > 0", {}};
  if (p.k1_n_m <= 0.0 || p.k2_n_m <= 0.0)
    return Error{"gantry axis stiffnesses k1_n_m, k2_n_m must be > 0", {}};
  if (p.c1_n_s_m < 0.0 || p.c2_n_s_m < 0.0)
    return Error{"gantry axis dampings c1_n_s_m, c2_n_s_m must be >= 0", {}};
  if (p.e_frac <= 0.0 || p.e_frac > 1.0) return Error{"belt efficiency e_frac must be in (0, 1]", {}};
  return {};
}

StateSpace gantry_state_space(const GantryAxisParams& p) {
  const double k2e = p.k2_n_m / p.e_frac;  // belt force on the motor side, Eq. 7 and Eq. 13
  StateSpace s;
  s.A = Eigen::MatrixXd::Zero(4, 4);
  s.A(0, 1) = 1.0;
  s.A(1, 0) = -(p.k1_n_m + k2e) / p.m1_kg;
  s.A(1, 1) = -p.c1_n_s_m / p.m1_kg;
  s.A(1, 2) = k2e / p.m1_kg;
  s.A(2, 3) = 1.0;
  s.A(3, 0) = p.k2_n_m / p.m2_kg;
  s.A(3, 2) = -p.k2_n_m / p.m2_kg;
  s.A(3, 3) = -p.c2_n_s_m / p.m2_kg;
  s.B = Eigen::MatrixXd::Zero(4, 1);
  s.B(1, 0) = p.k1_n_m / p.m1_kg;
  s.C = Eigen::MatrixXd::Zero(1, 4);
  s.C(0, 2) = 1.0;
  s.D = Eigen::MatrixXd::Zero(1, 1);
  return s;
}

Status validate(const CarriageMode& mode) {
  if (!(std::isfinite(mode.freq_hz) && std::isfinite(mode.damping) && std::isfinite(mode.mass_kg)))
    return Error{"carriage mode: frequency, damping and mass must be finite", {}};
  if (!(mode.mass_kg >= 0.0)) return Error{"carriage mode: mass_kg must be >= 0", {}};
  if (mode.present() && !(mode.freq_hz > 0.0 && mode.damping >= 0.0))
    return Error{"carriage mode: freq_hz must be > 0 and damping >= 0", {}};
  return {};
}

StateSpace gantry_state_space(const GantryAxisParams& p, const CarriageMode& mode) {
  StateSpace base = gantry_state_space(p);
  if (!mode.present()) return base;
  const double w = 2.0 * std::numbers::pi * mode.freq_hz;
  const double m3 = mode.mass_kg, k3 = m3 * w * w, c3 = 2.0 * mode.damping * m3 * w;
  StateSpace s;
  s.A = Eigen::MatrixXd::Zero(6, 6);
  s.A.topLeftCorner(4, 4) = base.A;
  // The mount's force on the carriage, k3 (x3 - x2) + c3 (x3' - x2'); the opposite on m3.
  s.A(3, 2) -= k3 / p.m2_kg;
  s.A(3, 3) -= c3 / p.m2_kg;
  s.A(3, 4) = k3 / p.m2_kg;
  s.A(3, 5) = c3 / p.m2_kg;
  s.A(4, 5) = 1.0;
  s.A(5, 2) = k3 / m3;
  s.A(5, 3) = c3 / m3;
  s.A(5, 4) = -k3 / m3;
  s.A(5, 5) = -c3 / m3;
  s.B = Eigen::MatrixXd::Zero(6, 1);
  s.B(1, 0) = base.B(1, 0);
  s.C = Eigen::MatrixXd::Zero(1, 6);
  s.C(0, 2) = 1.0;
  s.D = Eigen::MatrixXd::Zero(1, 1);
  return s;
}

TransferFunction gantry_transfer_function(const GantryAxisParams& p) {
  const double m1 = p.m1_kg, m2 = p.m2_kg, k1 = p.k1_n_m, k2 = p.k2_n_m;
  const double c1 = p.c1_n_s_m, c2 = p.c2_n_s_m, k2e = k2 / p.e_frac;
  const double lead = m1 * m2;
  // Eq. 16 (with k2 -> k2/e where the belt acts on the motor).
  return TransferFunction{{k1 * k2 / lead},
                          {1.0, (c1 * m2 + c2 * m1) / lead, (c1 * c2 + (k1 + k2e) * m2 + k2 * m1) / lead,
                           (c1 * k2 + c2 * (k1 + k2e)) / lead, k1 * k2 / lead}};
}

// Eq. 18.
GantryFittedTf thesis_eq18_x() { return {6.69158e11, 16380.8, 7.82543e6, 4.82342e9, 6.65380e11}; }
GantryFittedTf thesis_eq18_y() { return {5.44776e10, 3220.54, 3.38821e6, 2.70238e8, 5.56597e10}; }

}  // namespace feedloop::model
