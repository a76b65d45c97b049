// One belt-driven axis of the second simulator (docs/plant2.md): a hybrid stepper (rotor inertia,
// sinusoidal torque against the field's angle, microstep angle error, detent torque), a toothed
// belt loop as a ring of 3 N lumped masses and springs whose stiffness follows the free length of
// each span (so it changes with the carriage's position), a carriage on LuGre friction, an
// optional extra resonance, and a linear encoder with interpolation error, scale error and
// transport delay.
//
// Coordinates: every belt node and the carriage carry their displacement along the loop in m (the
// carriage's is its axis position); the rotor its angle theta in rad, the belt's pitch line at the
// pulley being p(theta) = r theta + e sin(theta + p_e) (runout). Thesis Eq. 11: x_1 = r theta.
//
// Integration: semi-implicit (symplectic) Euler on the flat state arrays, one force evaluation per
// step; the field's lag and the LuGre bristle state advance with their exact solutions over the
// step. The step rule (max_step_s): dt = 1.5 / max_i (sqrt(2 K_i / m_i) + 2 C_i / m_i) over every
// degree of freedom i, K_i and C_i the sums of the stiffness and damping attached to it at the
// stiffest geometry (both variable spans at min_span_m): a Gershgorin bound on the largest
// eigenvalue of M^-1 K and of M^-1 C, so the fastest mode has omega dt <= 1.5 (semi-implicit
// Euler is stable below 2; the measured modes, < 1 kHz, have omega dt < 0.02). Nothing allocates
// after create().
#pragma once

#include <cstddef>
#include <vector>

#include "core/result.hpp"
#include "plant2/encoder.hpp"
#include "plant2/lugre.hpp"
#include "plant2/params.hpp"

namespace feedloop::plant2 {

class Axis2 {
 public:
  // Builds the axis at rest at p.start_m (field at u = start_m, rotor in its static equilibrium
  // against the torque law and the detent, the belt unstretched). Errors: validate(p).
  static Result<Axis2> create(const Axis2Params& p);

  // The integration step rule (see above); advance() never steps longer than this.
  double max_step_s() const { return max_step_s_; }

  // One integration step of dt_s (<= max_step_s) with the field commanded to u_m (the microstep
  // staircase's value, in m of belt at the pulley) held over the step.
  void step(double u_m, double dt_s);
  // The spans' lengths (stiffness, masses) follow the carriage, refreshed every 0.1 mm.
  // Advances by duration_s with u held, in ceil(duration / max_step) equal steps.
  void advance(double u_m, double duration_s);

  double time_s() const { return t_s_; }
  double carriage_m() const { return x_[carriage_]; }
  double carriage_velocity_m_s() const { return v_[carriage_]; }
  double rotor_angle_rad() const { return theta_; }
  double rotor_position_m() const { return params_.stepper.pulley_radius_m * theta_; }
  double field_angle_rad() const { return phi_f_; }  // electrical
  double lugre_z_m() const { return friction_.z_m(); }
  // Kinetic energy of every mass and the rotor (J).
  double kinetic_energy_j() const;

  // The encoder's reading now, relative to its power-on reading and offset to start_m (so it
  // reads start_m at rest at the start): raw (no quantisation; the External plant v1 answer) and
  // quantised to resolution_m.
  double measured_m() const;
  double measured_quantised_m() const;
  const Encoder& encoder() const { return encoder_; }

  const Axis2Params& params() const { return params_; }
  size_t degrees_of_freedom() const { return x_.size() + 1; }

  // The spans' free lengths for a carriage at x (clamped at min_span_m) and the belt's
  // stiffness felt by the carriage with the pulley held, k^ / l_1 + k^ / (l_2 + l_3) (N/m).
  static void span_lengths(const BeltParams& b, double x_m, double out_m[3]);
  static double belt_stiffness_n_m(const BeltParams& b, double x_m);

 private:
  explicit Axis2(const Axis2Params& p);
  void update_geometry(double x_m);  // segment stiffness, damping and node masses for span lengths
  void set_field_target(double u_m);
  double compute_max_step() const;
  double pulley_m(double theta) const;
  double pulley_gain_m(double theta) const;  // dp/dtheta

  Axis2Params params_;
  int n_ = 4;        // segments per span
  size_t ring_ = 0;  // 3 n ring nodes: 0 the belt on the pulley, n the carriage, 2 n the idler
  size_t carriage_ = 0;
  size_t extra_ = 0;  // the extra resonance's mass (index ring_), when present
  bool has_extra_ = false;
  bool rigid_wrap_ = true;  // no backlash: node 0 rides on the pulley

  // Flat state and per-step scratch (sized at create()).
  std::vector<double> x_, v_, f_, inv_m_, m_;
  std::vector<double> k_seg_, c_seg_;  // ring segment s joins node s and s + 1 (mod ring_)
  double k_span_[3] = {0.0, 0.0, 0.0};
  double c_span_[3] = {0.0, 0.0, 0.0};
  double theta_ = 0.0, omega_ = 0.0;
  double phi_f_ = 0.0;       // the field's electrical angle
  double phi_target_ = 0.0;  // where the field is driven (commanded angle plus microstep error)
  double u_cached_m_ = 0.0;
  double decay_dt_ = -1.0, decay_ = 0.0;  // exp(-dt / tau) for the last dt
  double extra_k_ = 0.0, extra_c_ = 0.0;
  double tooth_c_ = 0.0;
  double ln_ratio_half_ = 0.0;
  double geometry_x_m_ = 0.0;  // the carriage position the spans' lengths were computed for
  double t_s_ = 0.0;
  double max_step_s_ = 1e-6;
  double encoder_zero_m_ = 0.0;
  LuGre friction_;
  Encoder encoder_;
};

}  // namespace feedloop::plant2
