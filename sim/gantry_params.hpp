// Parameters of one belt-driven stepper axis (closed-loop-gantry thesis, Appendix D) and of the
// optional effects that identification must find without being told (DESIGN.md vocabulary).
//
// Defaults and presets: see docs/simulator.md ("Gantry parameters"). The presets use the masses
// of Table 3 and the k1, k2, c1, c2 that make the linearised model's denominator (Eq. 16) equal
// to the fitted Eq. 18 exactly; Table 4 gives the same values rounded to three digits.
#pragma once

#include <cstdint>  // uint64_t
#include <limits>

#include "core/result.hpp"
#include "sim/encoder.hpp"

namespace feedloop::sim {

// Each effect is OFF unless `enabled`; parameter names follow the identification vocabulary.
struct CoulombFriction {
  bool enabled = false;
  double force_n = 0.0;  // sliding friction on the carriage, N
};
struct Backlash {
  bool enabled = false;
  double width_um = 0.0;  // total dead band between pulley and belt on a reversal
};
struct PeriodicPosition {  // pulley runout / microstep nonlinearity
  bool enabled = false;
  double period_mm = 33.93;  // one pulley revolution at r = 5.40 mm
  double amplitude_um = 0.0;
};
struct ExtraResonance {  // a third mass on a flexible mount on the carriage (e.g. a hotend, a cable chain)
  bool enabled = false;
  double freq_hz = 0.0;   // natural frequency of the mass on its mount, sqrt(k3 / m3)
  double damping = 0.05;  // damping ratio of the mount
  double mass_kg = 0.15;  // m3; the carriage shows an anti-resonance at freq_hz and a resonance just above
};
struct TimeDelay {
  bool enabled = false;
  double delay_ms = 0.0;  // extra delay of the encoder reading behind the carriage
};
struct ScaleError {
  bool enabled = false;
  double scale = 1.0;  // true mm per step / nominal mm per step, e.g. 1.003
};

struct GantryEffects {
  CoulombFriction coulomb_friction;
  Backlash backlash;
  PeriodicPosition periodic_position;
  ExtraResonance extra_resonance;
  TimeDelay time_delay;
  ScaleError scale_error;
};

struct GantryAxisParams {
  // Stepper motor (Eq. 1-3, 8, 14). Linear coordinates x1 = -r*theta (Eq. 11).
  double motor_stiffness_n_m = 354562.0;  // k1 = T_max n_r / r^2 (Eq. 14); sets T_max via the sine law
  double rotor_mass_kg = 0.130;           // m1 = J / r^2, J = 38 g cm^2 (Table 2-3)
  double motor_damping_n_s_m = 2097.19;   // c1 = c1' / r^2 (Eq. 9, 14)
  double pulley_radius_mm = 5.40;         // r (Table 2)
  int full_steps_per_rev = 200;           // 1.8 deg hybrid stepper: n_r = full_steps_per_rev / 4 rotor teeth
  int microsteps = 16;                    // the equilibrium moves by one microstep per step pulse
  // Pull-out force falls with speed (the winding inductance of Eq. 3 limits the phase current):
  // Every electromagnetic force is scaled by 1 / sqrt(1 + (v1 / corner)^2). 0 disables the
  // roll-off. Calibrated so the presets reproduce Sect. 5.3-5.4 qualitatively (docs/simulator.md).
  double pullout_corner_speed_mm_s = 100.0;
  // Belt (Eq. 5-7): K2 = k_hat / (L - (x0 + x2) sgn(x1 - x2)) with k_hat = belt_stiffness * L,
  // so K2 = belt_stiffness_n_m at x0 + x2 = 0 (the identification position) in both directions.
  double belt_stiffness_n_m = 109783.0;  // k2
  double belt_span_mm = 350.0;           // L, distance between the pulleys
  double belt_x0_mm = 0.0;               // x0
  double efficiency = 1.0;               // e (Eq. 7, 13)
  // Carriage (Eq. 4, 10).
  double carriage_mass_kg = 0.45;        // m2
  double bearing_damping_n_s_m = 111.845;  // c2
  // A hard stop (the frame at the travel's end, stall homing's reference): a stiff contact
  // (hard_stop_n_m, damped at zeta 0.5) that pushes the carriage back past this position;
  // infinite: none. min: the carriage stops below it; max: above.
  double hard_stop_min_mm = -std::numeric_limits<double>::infinity();
  double hard_stop_max_mm = std::numeric_limits<double>::infinity();
  double hard_stop_n_m = 2.0e5;
  // The belt will get hard stops on a coordinate it shares with another belt (a CoreXY carriage:
  // GantryAxis::add_coupled_stop): the substep rate allows for the contact's mode.
  bool coupled_stops = false;
  double initial_pos_mm = 0.0;           // carriage position x2 at power-on (encoder and steps zero here)

  EncoderParams encoder;
  GantryEffects effects;
  // Fixed RK4 step rate; step events split a substep at their exact time. 0: from the plant's
  // fastest mode (GantryAxis::fastest_mode_rad_s, kRk4HOmegaMax in sim/linearize.hpp).
  double substep_hz = 0.0;
  uint64_t seed = 1;            // encoder noise
};

// The thesis's X axis (extruder carriage, m2 = 0.45 kg) and Y axis (X gantry, m2 = 1.07 kg).
GantryAxisParams thesis_x_axis();
GantryAxisParams thesis_y_axis();

Status validate(const GantryAxisParams& p);

}  // namespace feedloop::sim
