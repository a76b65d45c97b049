// The output-maneuvering control law (see controller.hpp for the equations).
#include "maneuver/controller.hpp"

namespace feedloop::maneuver {

ManeuverController::ManeuverController(const CartesianDcPlant& plant, const ManeuverGains& gains)
    : mat_(plant.matrices()),
      gravity_offset_v_(plant.gravity_offset_v()),
      g_(gains),
      p1_(gains.q1 / (2.0 * gains.k_p)),   // P_1 A_1 + A_1^T P_1 = -Q_1 with A_1 = -K_p
      p2_(gains.q2 / (2.0 * gains.k_d)) {} // P_2 A_2 + A_2^T P_2 = -Q_2 with A_2 = -K_d

ManeuverOutput ManeuverController::evaluate(const PiecewiseLinearPath& path, const SpeedAssignment& speed,
                                            const PlantState& x, const ManeuverState& c, size_t n) const {
  return evaluate_at(path.yd(c.theta, n), path.dyd(n), speed.at(path, c.theta, n), x, c);  // Eq. 21-22
}

ManeuverOutput ManeuverController::evaluate_at(const Vec3& yd, const Vec3& dyd, const SpeedValue& speed,
                                               const PlantState& x, const ManeuverState& c) const {
  ManeuverOutput o;
  o.speed = speed;
  const double v_s = o.speed.v_s;
  o.z1_m = x.x1_m - yd;                                             // Eq. 26
  const Vec3 alpha1 = -g_.k_p * o.z1_m + dyd * v_s;                 // Eq. 33/61
  o.z2_m_s = x.x2_m_s - alpha1;                                     // Eq. 27
  const Vec3 dalpha1 = g_.k_p * dyd + dyd * o.speed.dv_s_dtheta;    // Eq. 62
  // Eq. 45: M^-1 k_1 w = A_2 z_2 - P_2^-1 P_1 z_1 + M^-1 D x_2 + A_1 x_2 + dalpha_1/dtheta v_s.
  const double coupling = g_.as_printed ? 1.0 : -1.0;  // Eq. 58 as printed : Eq. 45
  const Vec3 accel = -g_.k_d * o.z2_m_s + coupling * (p1_ / p2_) * o.z1_m +
                     mat_.d_n_s_m.cwiseQuotient(mat_.m_kg).cwiseProduct(x.x2_m_s) -
                     g_.k_p * x.x2_m_s + dalpha1 * v_s;
  o.w_v = mat_.m_kg.cwiseProduct(accel) / mat_.k1_n_v;
  o.w_v.z() += gravity_offset_v_;                                   // Eq. 14
  o.dtheta = v_s - c.omega_s;                                       // Eq. 56
  const double zpb = p1_ * o.z1_m.dot(dyd) + p2_ * o.z2_m_s.dot(dalpha1);  // tau_1 + tau_2
  const double mu = g_.as_printed ? 2.0 * g_.mu : g_.mu;  // Eq. 57 as printed : Eq. 52
  o.domega_s = -g_.lambda * (c.omega_s + mu * zpb);       // Eq. 52
  o.lyapunov = 0.5 * p1_ * o.z1_m.squaredNorm() + 0.5 * p2_ * o.z2_m_s.squaredNorm() +
               c.omega_s * c.omega_s / (2.0 * g_.lambda * g_.mu);   // Eq. 51
  return o;
}

}  // namespace feedloop::maneuver
