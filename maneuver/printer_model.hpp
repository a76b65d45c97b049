// The Cartesian DC-motor 3D printer of output-maneuvering-cartesian Sect. III-A as a simulated
// plant with voltage-driven axes.
//
// Each axis is a timing belt driven by a DC motor with the electrical dynamics ignored (Eq. 3-4);
// the belt displacements q = [q_x, q_y, q_z] are the generalised coordinates (Eq. 5-10). The
// nozzle (m_N) rides on x, the print surface (m_PS) on y, the x gantry (m_X + m_N) on z:
//   (m_N + J_m/r^2) q_x'' + B/r^2 q_x' = K_m/(r R_a) V_x                                (Eq. 11)
//   (m_PS + J_m/r^2) q_y'' + B/r^2 q_y' = K_m/(r R_a) V_y                               (Eq. 12)
//   (m_N + m_X + J_m/r^2) q_z'' + B/r^2 q_z' + (m_N + m_X) g = K_m/(r R_a) V'_z         (Eq. 13)
// i.e. M q'' + D q' = u = k_1 w (Eq. 15-18) once V'_z = V_z + r R_a/K_m (m_N + m_X) g (Eq. 14).
// The plant keeps gravity (Eq. 13): the controller adds the Eq. 14 offset itself.
// State x_1 = q, x_2 = q' (Eq. 19-20). SI units throughout (m, m/s, V).
#pragma once

#include <Eigen/Core>

namespace feedloop::maneuver {

using Vec3 = Eigen::Vector3d;

// Table I. The values are the paper's example, not a real printer.
struct CartesianDcParams {
  double m_n_kg = 0.4;             // extruder system (nozzle)
  double m_x_kg = 0.2;             // x-axis motor
  double m_ps_kg = 0.8;            // print surface
  double j_m_kg_m2 = 5.0e-6;       // motor + shaft + pulley inertia
  double b_nm_s_rad = 1.1e-4;      // motor friction
  double r_a_ohm = 1.0e-3;         // armature resistance
  double k_m_nm_a = 1.0e-4;        // torque constant
  double r_m = 0.01;               // pulley radius
  double g_m_s2 = 9.81;
};

// The diagonal matrices of Eq. 16-17 (as vectors) and the input gain k_1 of Eq. 18.
struct PrinterMatrices {
  Vec3 m_kg;        // diag(M), Eq. 16
  Vec3 d_n_s_m;     // diag(D), Eq. 17
  double k1_n_v;    // k_1 = K_m / (r R_a), Eq. 18
  double gravity_n; // (m_N + m_X) g, the z load of Eq. 13
};
PrinterMatrices printer_matrices(const CartesianDcParams& p);

struct PlantState {
  Vec3 x1_m = Vec3::Zero();    // q: belt displacements (nozzle position relative to the surface)
  Vec3 x2_m_s = Vec3::Zero();  // q'
};

struct PlantDerivative {
  Vec3 dx1_m_s;
  Vec3 dx2_m_s2;
};

class CartesianDcPlant {
 public:
  explicit CartesianDcPlant(const CartesianDcParams& p = {}) : mat_(printer_matrices(p)), params_(p) {}

  const PrinterMatrices& matrices() const { return mat_; }
  const CartesianDcParams& params() const { return params_; }

  // Eq. 19-20 with the gravity load of Eq. 13; v_volts = [V_x, V_y, V'_z].
  PlantDerivative derivative(const PlantState& s, const Vec3& v_volts) const;

  // One classical RK4 step with the voltage held over the step (zero-order hold).
  void step_rk4(PlantState& s, const Vec3& v_volts, double dt_s) const;

  // The Eq. 14 offset r R_a / K_m (m_N + m_X) g added to V_z to cancel gravity.
  double gravity_offset_v() const { return mat_.gravity_n / mat_.k1_n_v; }

 private:
  PrinterMatrices mat_;
  CartesianDcParams params_;
};

}  // namespace feedloop::maneuver
