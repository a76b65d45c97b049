// The parameters of one belt-driven axis of the second simulator (docs/plant2.md): a stepper whose
// field follows the commanded microstep position, a toothed belt loop lumped into masses and
// springs, a carriage on LuGre friction, a linear encoder. Written from the closed-loop gantry
// thesis (Appendix D: Eq. 1-2, 4-7, 13-14, Tables 2-4) independently of sim/. SI units inside.
//
// The defaults are the thesis's X axis where it gives a number (J, n_r, r, m_2, holding torque
// derated to half the 0.285 N m rating, Table 2 and 3) and plausible values where it does not
// (belt EA and density of a 6 mm GT2 belt, frame geometry, friction levels); draw.hpp draws them
// around these.
#pragma once

#include "core/result.hpp"

namespace feedloop::plant2 {

struct StepperParams {
  double holding_torque_nm = 0.1425;    // T_max (Eq. 2): 0.285 N m at half current (Table 3, X)
  int rotor_teeth = 50;                 // n_r (Table 2): 1.8 deg hybrid, 200 full steps/rev
  int microsteps = 16;                  // per full step (the thesis's 16x driver)
  double rotor_inertia_kg_m2 = 3.8e-6;  // J = 38 g cm^2 (Table 2)
  double pulley_radius_m = 5.40e-3;     // r, effective (Table 2)
  // The field (phase currents) follows the commanded electrical angle through a first-order lag
  // (the driver's current loop, L/R against the chopper voltage).
  double field_tau_s = 60e-6;
  // Damping of the load angle (rotor speed relative to the field's speed): the electromagnetic
  // damping a current-driven stepper shows; c_1 of Eq. 13 is this over r^2 (Eq. 14).
  double field_damping_nm_s_rad = 250.0 * 5.40e-3 * 5.40e-3;
  double bearing_damping_nm_s_rad = 2e-6;  // rotor bearings, against the frame
  // Microstep angle error: the field's electrical angle is phi_c + a4 sin(4 phi_c + p4) +
  // a1 sin(phi_c + p1), phi_c = n_r u / r the commanded one. a4: once per full step (4 per
  // electrical cycle, the current table's error); a1: once per electrical cycle (phase offset).
  double microstep_err4_rad = 0.0;  // electrical radians
  double microstep_phase4_rad = 0.0;
  double microstep_err1_rad = 0.0;
  double microstep_phase1_rad = 0.0;
  // Detent (cogging) torque: -T_d sin(4 n_r theta + p_d), once per full step.
  double detent_torque_nm = 0.0;
  double detent_phase_rad = 0.0;
  // Pulley runout: the belt's pitch line at the pulley is at r theta + e sin(theta + p_e)
  // (eccentricity e: a position error once per pulley turn, period 2 pi r).
  double runout_m = 0.0;
  double runout_phase_rad = 0.0;
};

struct BeltParams {
  // The loop: motor pulley at x = -pulley_gap_m, idler at x = travel_m + end_gap_m. Span 1 runs
  // from the pulley to the carriage (free length pulley_gap_m + x), span 2 from the carriage to
  // the idler (travel_m + end_gap_m - x), span 3 back from the idler to the pulley (fixed).
  double specific_stiffness_n = 8000.0;  // k^ = E A of the belt (thesis Eq. 6: K_2 = k^ / length)
  double linear_density_kg_m = 7.5e-3;   // 6 mm GT2 belt
  int segments_per_span = 4;             // N >= 4 lumped segments on each of the three spans
  double pulley_gap_m = 0.040;
  double travel_m = 0.300;
  double end_gap_m = 0.040;
  double min_span_m = 0.025;    // spans shorter than this (carriage beyond travel) clamp
  double idler_mass_kg = 3e-3;  // idler inertia / radius^2
  // Damping: a damper across each span, c = beta k_span (the belt's material loss at the low
  // modes), and a small per-segment damper (ratio of the segment's own mode) that keeps the belt's
  // internal modes, far above anything measured, from ringing.
  double span_damping_s = 1e-4;  // beta
  double segment_damping_ratio = 0.05;
  // Backlash: dead band between the pulley's teeth and the belt (0 = the belt is on the pulley).
  double backlash_m = 0.0;
  double tooth_stiffness_n_m = 2e5;  // contact stiffness outside the dead band
  double tooth_damping_ratio = 0.3;  // of the belt-on-pulley node against the teeth
  // Direction-dependent stiffness: K(pulling +) / K(pulling -) (thesis Eq. 6's two cases).
  double stiffness_ratio = 1.0;
};

struct CarriageParams {
  double mass_kg = 0.45;  // m_2 (Table 2, X: extruder)
  // LuGre friction (Canudas de Wit et al. 1995): F = sigma0 z + sigma1 dz/dt + sigma2 v,
  // dz/dt = v - sigma0 |v| z / g(v), g(v) = F_c + (F_s - F_c) exp(-(v / v_s)^2).
  double coulomb_n = 0.15;             // F_c
  double static_n = 0.2;               // F_s (breakaway)
  double stribeck_m_s = 2e-3;          // v_s
  double bristle_stiffness_n_m = 5e4;  // sigma0
  double bristle_damping_n_s_m = 0.0;  // sigma1 (0: 0.3 of the bristles' critical damping)
  double viscous_n_s_m = 20.0;         // sigma2 (thesis c_2 = 71.5-112 N s/m is a linear fit's
                                       // whole damping, Table 4)
  // Extra resonance: a mass on a spring-damper on the carriage (0 kg = none).
  double extra_mass_kg = 0.0;
  double extra_freq_hz = 80.0;
  double extra_damping_ratio = 0.05;
};

struct EncoderParams {
  double resolution_m = 0.5e-6;     // quantisation step (0 = none)
  double interp_period_m = 20e-6;   // the scale's signal period
  double interp_amplitude_m = 0.0;  // interpolation error, sinusoidal at that period
  double interp_phase_rad = 0.0;
  double scale = 1.0;           // measured travel / true travel
  double delay_s = 0.0;         // transport delay of the measurement
  double max_delay_s = 2.5e-3;  // the delay line's capacity
};

struct Axis2Params {
  StepperParams stepper;
  BeltParams belt;
  CarriageParams carriage;
  EncoderParams encoder;
  double start_m = 0.100;  // the carriage at rest here, u = start at t = 0
};

// Errors: a non-positive mass, stiffness, radius or time constant; fewer than 4 segments; a delay
// outside [0, max_delay_s]; a carriage start outside the spans' geometry.
Status validate(const Axis2Params& p);

}  // namespace feedloop::plant2
