// One belt-driven stepper axis in the time domain: the thesis's NONLINEAR model (Appendix D,
// Eq. 1-7) with a microstepping driver, plus the optional effects of gantry_params.hpp.
//
// State (SI, positions in machine coordinates):
//   u_f  driver field position: the electromagnetic equilibrium, following the step command u
//        (one microstep per pulse) with time constant tau = c1/k1
//   x1, v1  rotor (linear coordinates, Eq. 11)     x2, v2  carriage
//   x3, v3  the extra_resonance mass on its mount on the carriage (only with that effect)
//   z       friction bristle deflection (only with the coulomb_friction effect)
// Forces:
//   motor  F_m = F_max(|v1|) sin(2 pi (u_f - x1) / lambda) + c1 (du_f/dt - v1)   (Eq. 2-3, 9)
//          lambda = 4 full steps (one electrical period, n_r teeth); F_max = k1 lambda / (2 pi)
//   belt   F_t = K2(x2, sgn) (x1 - x2), K2 of Eq. 6                               (Eq. 5-7)
//   rails  -c2 v2 (Eq. 10), plus Coulomb friction when enabled: a Dahl bristle model
//          dz/dt = v2 (1 - sgn(v2) z / z_max), F_c z / z_max, which sticks at rest (holds any
//          force below F_c) and slides with F_c, without a velocity singularity. Dahl's law is
//          one in displacement (dz/dx2 = 1 - sgn(dx2) z / z_max), so the integration takes z in
//          closed form from the carriage's displacement within a substep:
//          z = s z_max + (z0 - s z_max) exp(-|x2 - x2_0| / z_max), s = sgn(x2 - x2_0)
// In the linear regime this is exactly Eq. 13: k1 (u_f - x1) + c1 (du_f/dt - v1) = k1 (u - x1)
// - c1 v1 because tau du_f/dt = u - u_f with tau = c1/k1. Damping relative to the moving field
// (instead of to ground) is what lets the rotor run at print speeds: with the fitted c1 to ground
// the sine law's pull-out force would be used up by damping above ~17 mm/s. docs/simulator.md.
//
// The driver starts enabled and the step counter and encoder start at zero at initial_pos_mm.
// Owner: one thread (the simulation loop). Calls must come with non-decreasing times; an earlier
// time is applied at the current time and counted in late_events().
#pragma once

#include <array>
#include <cstdint>

#include <Eigen/Dense>

#include "core/result.hpp"
#include "drivers/device/motor_port.hpp"
#include "sim/encoder.hpp"
#include "sim/gantry_params.hpp"
#include "sim/linearize.hpp"

namespace feedloop::sim {

class GantryAxis final : public device::MotorPort {
 public:
  using State = Eigen::Matrix<double, 8, 1>;
  enum Index : int { kField = 0, kRotor, kRotorVel, kCarriage, kCarriageVel, kExtra, kExtraVel, kBristle };

  // With p.substep_hz = 0 the substep rate comes from fastest_mode_rad_s (substep_hz_for in
  // sim/linearize.hpp); params().substep_hz is the rate in use.
  static Result<GantryAxis> create(const GantryAxisParams& p);
  // The fastest mode of the plant anywhere in its travel (rad/s): the linearisation at rest, where
  // the motor's stiffness (the sine law's slope) and damping (full current) are largest, with the
  // belt as built and at its stiffest (Eq. 6 at the shortest active length the model allows, 20 k2)
  // (The friction bristle sets no rate: the integration takes it in closed form, bristle_at.)
  static double fastest_mode_rad_s(const GantryAxisParams& p);

  // MotorPort (RT-safe: no allocation).
  void step(double t_s, int direction) override;
  // The driver's current vector `fraction` of a microstep beyond the step count (direct current
  // control): the commanded position is (steps + fraction) x step.
  void set_step_fraction(double t_s, float fraction) override;
  void set_enabled(double t_s, bool enabled) override;
  int64_t read_encoder_counts(double t_s) override;
  bool read_encoder_index(double t_s) override;

  // Integrate to t_s with no event (RT-safe).
  void advance_to(double t_s);

  // Ground truth, for tests and benchmarks.
  double time_s() const { return t_s_; }
  double carriage_mm() const { return x_[kCarriage] * 1e3; }
  double carriage_velocity_mm_s() const { return x_[kCarriageVel] * 1e3; }
  double rotor_mm() const { return x_[kRotor] * 1e3; }
  double field_mm() const { return x_[kField] * 1e3; }
  double commanded_mm() const;          // initial_pos + steps * nominal mm per step (what the host sent)
  int64_t step_count() const { return steps_; }
  double mm_per_step() const { return mm_per_step_nominal_; }
  double encoder_mm_per_count() const { return encoder_.mm_per_count(); }
  // Steps lost so far: 4 * round((u_f - x1) / lambda), in full steps, positive when the rotor has
  // fallen behind the field in the + direction (the sine law has period 4 full steps).
  int64_t lost_full_steps() const { return 4 * slip_periods_; }
  int64_t slip_events() const { return slip_events_; }  // jumps to another equilibrium (each 4 full steps)
  int64_t late_events() const { return late_events_; }
  bool enabled() const { return enabled_; }
  const GantryAxisParams& params() const { return p_; }

  // The model: dx/dt for state x and step command u (m), with the current enable state.
  State derivative(const State& x, double u_m) const;
  double substep_s() const { return h_s_; }
  const State& state() const { return x_; }
  // Small-signal model around the current state (call at rest). Input: the field command u in
  // mm; output: carriage position in mm (what the encoder sees, before quantisation and delay).
  // Where x0 + x2 != 0 the belt is piecewise linear at rest (Eq. 6); the central difference then
  // gives the mean of its two stiffnesses. Non-smooth effects (backlash, friction) linearise to
  // their local slope.
  LinearModel linearize() const;

  // A hard stop on a coordinate this belt shares with another gantry (CoreXY: the carriage's
  // x = (A + B) / 2 and y = (A - B) / 2 of the belts' ends A and B): a contact on
  // c = own_coef * own + other_coef * other (carriage positions) below min_mm or above max_mm,
  // stiff and damped as the hard stops above, of which this belt takes own_coef times the force
  // (virtual work). The other gantry's committed state is read as it stands (the two are advanced
  // in turns, a step interval apart at most). At most two; `other` must outlive this gantry.
  // params.coupled_stops must have been set (the substep rate).
  void add_coupled_stop(const GantryAxis& other, double own_coef, double other_coef, double min_mm,
                        double max_mm);

 private:
  struct CoupledStop {
    const GantryAxis* other = nullptr;
    double own = 0.0, other_coef = 0.0, min_m = 0.0, max_m = 0.0;
  };
  explicit GantryAxis(const GantryAxisParams& p);
  // derivative() with the sine law's value sin(2 pi (u_f - x1) / lambda) given: RK4 evaluates it
  // once per substep and carries it to the stages by angle addition (integrate_).
  // What the stages of one substep take from its start: the pulley runout's phase with its sine
  // and cosine (the stages take theirs by angle addition, sin_near, as the sine law's), and the
  // carriage's position with the friction bristle's deflection (the stages take the bristle's
  // from the carriage's displacement since, in closed form: bristle_at).
  struct SubstepStart {
    double phase = 0.0, sin = 0.0, cos = 1.0;
    double carriage_m = 0.0, bristle_m = 0.0;
  };
  // from: the integration's stages (nullptr: the exact sine and the bristle's ODE, for the
  // linearisation).
  State derivative_(const State& x, double u_m, double sin_phase, const SubstepStart* from) const;
  void integrate_(State& x, double h_s) const;
  void after_substep_();
  void commit_substeps_(double t_s);
  void commit_to_(double t_s);
  void advance_to_view_();

  GantryAxisParams p_;
  LinearEncoder encoder_;
  History history_;
  // The committed state (xc_ at tc_s_: input events and whole substeps after them) and the view
  // (x_ at t_s_: the committed state integrated to the latest time looked at; the accessors').
  State xc_ = State::Zero();
  double tc_s_ = 0.0;
  State x_ = State::Zero();
  double t_s_ = 0.0;
  int64_t steps_ = 0;
  double step_fraction_ = 0.0;  // set_step_fraction
  bool enabled_ = true;
  double stop_min_m_ = 0.0, stop_max_m_ = 0.0, stop_c_ = 0.0;  // the hard stops (gantry_params.hpp)
  std::array<CoupledStop, 2> coupled_{};
  int num_coupled_ = 0;
  int64_t slip_periods_ = 0;
  int64_t slip_events_ = 0;
  int64_t late_events_ = 0;
  // Derived at construction.
  double h_s_ = 0.0;
  double mm_per_step_nominal_ = 0.0;
  double m_per_step_true_ = 0.0;
  double lambda_m_ = 0.0;    // electrical period
  double f_hold_n_ = 0.0;    // sine-law amplitude at standstill
  double tau_s_ = 0.0;       // field time constant c1/k1
  double k_hat_ = 0.0;       // belt unit stiffness, N (k2 * L)
  double read_delay_s_ = 0.0;
  // derivative_'s coefficients: the parameters in SI, reciprocals where the model divides.
  double phase_per_m_ = 0.0;     // 2 pi / lambda
  double inv_tau_per_s_ = 0.0;   // 1 / tau
  double inv_corner_s_m_ = 0.0;  // 1 / pull-out corner speed (0: no roll-off)
  double span_m_ = 0.0, x0_m_ = 0.0, min_active_m_ = 0.0;  // belt L, x0, shortest active length
  double inv_efficiency_ = 1.0, inv_m1_ = 0.0, inv_m2_ = 0.0;
  double runout_m_ = 0.0, runout_per_m_ = 0.0;  // periodic_position: amplitude, 2 pi / period
  double backlash_half_m_ = 0.0;
  double friction_n_per_m_ = 0.0;                        // Coulomb: F_c / z_max
  double extra_k_ = 0.0, extra_c_ = 0.0, inv_m3_ = 0.0;  // mount of the extra_resonance mass
  double u0_m_ = 0.0;  // step command at zero steps (initial position)
};

}  // namespace feedloop::sim
