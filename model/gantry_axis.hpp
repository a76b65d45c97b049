// Linear two-mass model of one belt-driven stepper axis of the thesis gantry
// (closed-loop-gantry-thesis.txt, Appendix D.2-D.3, Eq. 13-18, Tables 2-4).
//
//   m1 x1'' = -k1 (x1 - u) + (k2/e)(x2 - x1) - c1 x1'      (Eq. 13, motor side, linear coordinates)
//   m2 x2'' = -k2 (x2 - x1) - c2 x2'                       (Eq. 13, carriage/load side)
// u: magnetic equilibrium position commanded by the driver; y = x2: carriage position.
// m1 = J/r^2, k1 = T_max n_r / r^2, c1 = c1'/r^2 (Eq. 14). Position-to-position: static gain 1
// for every e (at rest x2 = x1 = u).
#pragma once

#include "core/result.hpp"
#include "model/lti.hpp"

namespace feedloop::model {

struct GantryAxisParams {
  double m1_kg = 0.130;       // motor inertia as a mass, J/r^2 (Table 3)
  double m2_kg = 0.45;        // load mass (Table 2)
  double k1_n_m = 355e3;      // motor "spring" T_max n_r / r^2 (Table 4)
  double k2_n_m = 110e3;      // belt spring (Table 4)
  double c1_n_s_m = 2100.0;   // motor damping (Table 4)
  double c2_n_s_m = 112.0;    // bearing damping (Table 4)
  double e_frac = 1.0;        // belt transmission efficiency e (Eq. 7); Eq. 16 assumes e = 1
};

// Table 3-4 parameters of the thesis's X axis (extruder carriage) and Y axis (whole X gantry).
GantryAxisParams thesis_x_axis();
GantryAxisParams thesis_y_axis();

// Masses, stiffnesses > 0, dampings >= 0, 0 < e <= 1, all finite.
Status validate(const GantryAxisParams& p);

// Eq. 15 with state q = [x1, x1', x2, x2'], input u, output y = x2 (SI: m, m/s).
StateSpace gantry_state_space(const GantryAxisParams& p);

// A mode the two masses lack (what `feedloop ident fit` reports as extra_resonance): a mass m3 on
// a spring-damper on the carriage, k3 = m3 w^2 and c3 = 2 zeta m3 w with w = 2 pi freq_hz (its
// natural frequency clamped to the carriage). mass_kg 0: none.
struct CarriageMode {
  double freq_hz = 0.0;
  double damping = 0.0;
  double mass_kg = 0.0;
  bool present() const { return mass_kg > 0.0; }
};
// freq_hz, damping, mass_kg finite, freq_hz > 0, damping >= 0, mass_kg >= 0.
Status validate(const CarriageMode& mode);

// Eq. 15 with the mode's mass on the carriage: q = [x1, x1', x2, x2', x3, x3'] (x3 the mode's
// mass), the carriage's equation gaining k3 (x3 - x2) + c3 (x3' - x2'); output y = x2. Without a
// mode: gantry_state_space(p).
StateSpace gantry_state_space(const GantryAxisParams& p, const CarriageMode& mode);

// Eq. 16 generalised to any e (Eq. 16 is the case e = 1):
//   G(s) = k1 k2 / { m1 m2 s^4 + (c1 m2 + c2 m1) s^3 + (c1 c2 + (k1 + k2/e) m2 + k2 m1) s^2
//                    + (c1 k2 + c2 (k1 + k2/e)) s + k1 k2 },
// returned normalised to a monic denominator as in Eq. 17.
TransferFunction gantry_transfer_function(const GantryAxisParams& p);

// The fitted structure of Eq. 17: phi0 / (s^4 + psi3 s^3 + psi2 s^2 + psi1 s + psi0).
struct GantryFittedTf {
  double phi0, psi3, psi2, psi1, psi0;
  TransferFunction tf() const { return {{phi0}, {1.0, psi3, psi2, psi1, psi0}}; }
};

// The Matlab fits of Eq. 18 for the X and Y axes.
GantryFittedTf thesis_eq18_x();
GantryFittedTf thesis_eq18_y();

// K2(x) / k2 of a belt whose compliance is affine along the travel (what `feedloop calibrate`
// fits: ident/axis_model.hpp, control/feedforward/gantry_lpv.hpp): 1 / (1 + s (x - reference)),
// s in 1/m, held within 0.2-5 (a slope fitted on a part of the travel, read beyond it).
inline double belt_stiffness_factor(double slope_per_m, double reference_mm, double x_mm) {
  const double c = 1.0 + slope_per_m * (x_mm - reference_mm) * 1e-3;
  return 1.0 / (c < 0.2 ? 0.2 : (c > 5.0 ? 5.0 : c));
}

}  // namespace feedloop::model
