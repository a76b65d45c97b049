// The identification's model of one belt-driven stepper axis: the thesis's linear two-mass model
// (Appendix D, Eq. 13; its transfer function is the 4th-order Eq. 16-17) as the baseline, plus the
// candidate effects of the DESIGN.md vocabulary, each a switch with the vocabulary's parameters.
//
// simulate() runs it on a commanded-position sequence sampled at period_s:
//   m1 x1'' = k1 (u - x1) - c1 x1' - F_belt          (Eq. 13 motor side, e = 1)
//   m2 x2'' = F_belt - c2 x2' + F_fric + F_mount     (Eq. 13 carriage side + effects)
//   F_belt  = K2(sgn) * deadzone(x1 + A_p sin(2 pi x1 / P) - x2, w/2)
// The linear part is stepped exactly (Eigen's matrix exponential) with u interpolated linearly
// between samples (the step pulses of a sample are spread evenly over its interval); the effect
// forces (backlash, belt direction, runout, Dahl friction) are held over each step: 5 substeps
// per sample with a switching effect (backlash, belt direction, friction), one otherwise. scale_error scales u about its first sample; time_delay
// delays the output (linear interpolation); extra_resonance adds a third mass on a spring-damper
// to the carriage (three states more, all linear).
#pragma once

#include <string>
#include <vector>

#include "core/result.hpp"
#include "model/lti.hpp"

namespace feedloop::ident {

// The effect vocabulary (DESIGN.md). Names as written in report.json.
enum class Effect { kPeriodicPosition, kCoulombFriction, kBacklash, kDirectionStiffness, kExtraResonance,
                    kTimeDelay, kScaleError };
inline constexpr int kEffectCount = 7;
const char* effect_name(Effect e);

struct AxisModel {
  // Baseline physical parameters (Eq. 13-14), SI. The masses are not identifiable from a
  // position-to-position response; they are fixed (Tables 3-4 method: weigh them), the rest fitted.
  double m1_kg = 0.130, m2_kg = 0.45;
  double k1_n_m = 354562.0, k2_n_m = 109783.0, c1_n_s_m = 2097.19, c2_n_s_m = 111.845;

  bool enabled[kEffectCount] = {};
  // periodic_position: runout u + a sin + b cos of 2 pi x1 / P (amplitude_um = hypot(a, b)).
  double period_mm = 33.93, periodic_sin_um = 0.0, periodic_cos_um = 0.0;
  // The axis starts at rest with the runout's value at its start position (b) already in the belt,
  // and the measurement counts from that rest reading (an incremental encoder zeroed at power-on):
  // the output is x2 - b at the start, a sin + b (cos - 1) quasi-statically.
  double friction_force_n = 0.0;     // coulomb_friction (Dahl) ...
  double presliding_um = 20.0;       // ... its bristle deflection at full sliding friction (fitted)
  double backlash_width_um = 0.0;    // backlash: total dead band in the belt
  double stiffness_ratio = 1.0;      // direction_dependent_stiffness: K2(pulling +) / K2(pulling -)
  double extra_freq_hz = 60.0, extra_damping = 0.05, extra_mass_kg = 0.15;  // extra_resonance
  double delay_ms = 0.0;             // time_delay of the measurement
  double scale = 1.0;                // scale_error: true travel / commanded travel
  // The belt's compliance along the travel, the LPV baseline's position dependence (thesis Eq. 6
  // makes it the span's length; here without a geometry): 1 / K2(x) = (1 / k2) (1 + s (x - x_ref))
  // at carriage position x, so k2 is the stiffness at x_ref. s in 1/m, 0: a uniform belt. Not an
  // effect of the vocabulary: fit.cpp fits it on the carried model (IdentResult::carried).
  double compliance_slope_per_m = 0.0;
  double stiffness_reference_mm = 0.0;
  // The driver's field lag, ms, with c1 damping the load angle (the rotor against the moving
  // field) rather than the rotor against the frame: the motor then follows
  // u_eff = u (1 + T s) / (1 + field_lag s), T = c1 / k1, through Eq. 13 (Tustin at the sample
  // period, as the LPV feedforward inverts it). 0: Eq. 13 as written (the same as field_lag = T).
  // Not an effect of the vocabulary: fit.cpp fits it on the carried model (IdentResult::carried).
  double field_lag_ms = 0.0;

  bool has(Effect e) const { return enabled[static_cast<int>(e)]; }
  void set(Effect e, bool on) { enabled[static_cast<int>(e)] = on; }
  double periodic_amplitude_um() const;
};

// u filtered by the field lag's (1 + T s) / (1 + field_lag s) (Tustin at period_s, T = c1 / k1,
// the filter at rest at u[0]); u itself when m.field_lag_ms is 0.
std::vector<double> field_command(const AxisModel& m, const std::vector<double>& u_mm,
                                  double period_s);

// The baseline model of the thesis's X or Y axis (Tables 3-4 as solved in docs/simulator.md);
// any other axis name gets the X values as the starting point.
AxisModel preset_axis_model(const std::string& axis_name);

// Monic 4th-order denominator of Eq. 16/17 from the physical parameters (psi3, psi2, psi1, psi0).
void eq17_coefficients(const AxisModel& m, double psi[4]);

// The linear part (baseline, and the extra resonance when enabled) as a state space from the
// commanded position u (m) to the carriage position x2 (m): 4 states, 6 with the extra resonance.
// The nonlinear effects, the delay and the scale are not in it.
model::StateSpace axis_state_space(const AxisModel& m);

// Simulated carriage position (mm) for commanded positions u_mm sampled at period_s; starts at rest
// at u_mm[0]. y has u_mm's length. Errors: non-positive period, non-finite parameters.
Status simulate_axis(const AxisModel& m, const std::vector<double>& u_mm, double period_s, std::vector<double>* y_mm);

}  // namespace feedloop::ident
