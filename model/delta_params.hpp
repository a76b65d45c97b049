// Physical parameters of the delta LPV model, named after the symbols of the delta paper
// (delta-lpv-receptance-coupling.txt, Table I) with their units. The defaults are Table I's
// physical parameters; Table I's omega_n, omega'_n, zeta, zeta' are NOT used because they disagree
// with its m_c, m_f, c, b, k (docs/model.md, DESIGN.md "Facts worth knowing").
#pragma once

#include "core/result.hpp"
#include "model/delta_kinematics.hpp"

namespace feedloop::model {

struct DeltaParams {
  // Sub-model 1: carriage + belt (Eq. 30-44).
  double m_c_kg = 0.179;       // lumped carriage mass
  double m_f_kg = 0.032;       // mass of one pair of forearms; half of it rides on the carriage (Eq. 30)
  double c_n_s_m = 5.31;       // belt damping c
  double b_n_s_m = 13.4;       // guideway friction b
  double k_n_m = 1.21e5;       // belt stiffness k
  double d0_per_s2 = 1.43e5;   // electrical dynamics G_qd,e = (d1 s + d0)/(s^2 + d2 s + d0), Eq. 34
  double d1_per_s = -212.1;    //   d1 < 0: right-half-plane zero at -d0/d1 = 674 rad/s
  double d2_per_s = 36.2;

  // Sub-model 2: two-mass end-effector (Eq. 45-67).
  double m1_kg = 0.542;        // nozzle holder mass (carries the arm joints)
  double m2_kg = 0.109;        // extruder motor mass; 0 means a rigid one-mass effector (W = m1 s^2)
  double b_x_n_s_m = 20.4;     // b_j, coupling damping per task axis
  double b_y_n_s_m = 40.5;
  double b_z_n_s_m = 19.6;
  double k_x_n_m = 3.31e3;     // k_j, coupling stiffness per task axis
  double k_y_n_m = 7.04e3;
  double k_z_n_m = 1.29e5;

  // Mass distribution (Eq. 20): centroid-to-centre-of-mass offset and joint radius.
  double delta_x_mm = 10.21;
  double delta_y_mm = -16.52;
  double delta_z_mm = 19.31;
  double D_e_mm = 39.91;

  // The paper's W (Eq. 61) holds m1 and m2 only, although Fig. 3(a) puts half of each forearm
  // pair on the effector. true adds 3 m_f/2 to m1 (not the paper; off by default).
  bool forearm_half_mass_on_m1 = false;

  DeltaGeometry geometry;

  // Eq. 30: m = m_c + m_f/2.
  double m_kg() const { return m_c_kg + 0.5 * m_f_kg; }
  // m1 as used in W(s) (see forearm_half_mass_on_m1).
  double m1_effective_kg() const { return m1_kg + (forearm_half_mass_on_m1 ? 1.5 * m_f_kg : 0.0); }
};

// Table I (the defaults above).
inline DeltaParams delta_table1_params() { return DeltaParams{}; }

// Masses > 0 (m2 >= 0), stiffnesses > 0, dampings >= 0, d0 > 0, d2 > 0, D_e > 0, finite values,
// and a valid geometry. The message names the offending field.
Status validate(const DeltaParams& p);

}  // namespace feedloop::model
