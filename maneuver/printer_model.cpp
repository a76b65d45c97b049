// The Cartesian DC-motor printer plant (see printer_model.hpp for the equations).
#include "maneuver/printer_model.hpp"

namespace feedloop::maneuver {

PrinterMatrices printer_matrices(const CartesianDcParams& p) {
  const double jr2 = p.j_m_kg_m2 / (p.r_m * p.r_m);  // J_m / r^2: motor inertia seen by the belt
  const double br2 = p.b_nm_s_rad / (p.r_m * p.r_m); // B / r^2
  PrinterMatrices m;
  m.m_kg = Vec3(p.m_n_kg + jr2, p.m_ps_kg + jr2, p.m_n_kg + p.m_x_kg + jr2);  // Eq. 16
  m.d_n_s_m = Vec3::Constant(br2);                                             // Eq. 17
  m.k1_n_v = p.k_m_nm_a / (p.r_m * p.r_a_ohm);                                 // Eq. 18
  m.gravity_n = (p.m_n_kg + p.m_x_kg) * p.g_m_s2;                              // Eq. 13
  return m;
}

PlantDerivative CartesianDcPlant::derivative(const PlantState& s, const Vec3& v_volts) const {
  Vec3 force_n = mat_.k1_n_v * v_volts - mat_.d_n_s_m.cwiseProduct(s.x2_m_s);
  force_n.z() -= mat_.gravity_n;
  return {s.x2_m_s, force_n.cwiseQuotient(mat_.m_kg)};  // Eq. 19, Eq. 20 (+ gravity, Eq. 13)
}

void CartesianDcPlant::step_rk4(PlantState& s, const Vec3& v, double h) const {
  auto add = [](const PlantState& a, const PlantDerivative& d, double k) {
    return PlantState{a.x1_m + k * d.dx1_m_s, a.x2_m_s + k * d.dx2_m_s2};
  };
  const PlantDerivative k1 = derivative(s, v);
  const PlantDerivative k2 = derivative(add(s, k1, 0.5 * h), v);
  const PlantDerivative k3 = derivative(add(s, k2, 0.5 * h), v);
  const PlantDerivative k4 = derivative(add(s, k3, h), v);
  s.x1_m += h / 6.0 * (k1.dx1_m_s + 2.0 * k2.dx1_m_s + 2.0 * k3.dx1_m_s + k4.dx1_m_s);
  s.x2_m_s += h / 6.0 * (k1.dx2_m_s2 + 2.0 * k2.dx2_m_s2 + 2.0 * k3.dx2_m_s2 + k4.dx2_m_s2);
}

}  // namespace feedloop::maneuver
