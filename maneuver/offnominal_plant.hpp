// A plant for the DC-motor printer that is not the controller's model (issue 19).
//
// The controller (controller.hpp) keeps the nominal model of output-maneuvering-cartesian
// Sect. III-A: one rigid mass per axis, M q'' + D q' = k_1 w (Eq. 15-18), the voltage a force at
// once, the state measured exactly. This plant adds what a machine has and that model lacks, each
// switchable and sized by OffNominalParams (draw_offnominal() draws every size at random):
//
//   electrical   L di/dt = V - R_a i - K_m omega   (Eq. 3 has neither L nor the back-EMF K_m omega,
//                which adds (K_m/r)^2 / R_a = 0.1 N s/m of damping to Table I's B/r^2 = 1.1)
//   drive limits |V| <= V_max, |i| <= i_max (stated as the force F_max = K_m i_max / r)
//   belt         the pulley side (J_m / r^2 + B / r^2) and the carriage (m) joined by a spring
//                k_b and a damper c_b, instead of Eq. 11-13's single rigid mass:
//                  (J_m/r^2) q_m'' = K_m i / r - (B/r^2) q_m' - F_b,  F_b = k_b (q_m - q_c) + c_b
//                  (q_m' - q_c') m q_c''          = F_b - F_f(q_c') [- m g on z]
//   friction     Stribeck on the carriage: F_f(v) = (F_c + (F_s - F_c) exp(-(v/v_s)^2))
//   tanh(v/v_eps);
//                the smoothed sign lets a carriage held below breakaway creep (v_eps 0.1 mm/s: at
//                83 % of F_s, 0.12 mm/s), the price of integrating it at a fixed 10 us step
//   parameters   masses, J_m, B, K_m and R_a as multiples of Table I's
//   sensing      an encoder of finite resolution on the motor shaft (collocated) or on the
//                carriage, read after a transport delay; the velocity either exact or differenced
//                from the encoder's counts over the control period and low-pass filtered.
//
// The nozzle is the carriage (q_c): the cross-track error is taken on it, not on what the
// encoder reads. Integration: classical RK4 at a fixed substep (10 us default: the belt mode,
// the electrical pole and the friction smoothing are all slower than 1/(10 us) by 20x or more).
// Table I's motor is not a real one (R_a 1 mOhm, K_m 1e-4 N m/A: 10 N per volt and 1000 A per
// volt at stall), so the current limit is given as the force it allows.
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "maneuver/printer_model.hpp"
#include "maneuver/sampled_plant.hpp"

namespace feedloop::maneuver {

struct OffNominalParams {
  CartesianDcParams nominal{};  // Table I: what the controller believes
  // The machine's parameters as multiples of Table I's (1: as the controller believes).
  Vec3 mass_scale = Vec3::Ones();  // carriage masses: m_N (x), m_PS (y), m_N + m_X (z)
  double motor_inertia_scale = 1.0;
  double viscous_scale = 1.0;               // B
  double torque_constant_scale = 1.0;       // K_m (also the back-EMF constant)
  double resistance_scale = 1.0;            // R_a
  bool back_emf = false;                    // the motor's EMF K_m omega (Eq. 3 leaves it out)
  double electrical_time_constant_s = 0.0;  // L / R_a; 0: no inductance (Eq. 3)
  double voltage_limit_v = 0.0;             // 0: none
  double force_limit_n = 0.0;               // the current limit as a force; 0: none
  double belt_stiffness_n_m = 0.0;          // 0: rigid (one mass, Eq. 11-13)
  double belt_damping_ratio = 0.05;         // of the belt mode, sets c_b
  double coulomb_n = 0.0;                   // F_c; 0 with static_n 0: no friction
  double static_n = 0.0;                    // F_s (>= F_c)
  double stribeck_velocity_m_s = 1e-3;      // v_s
  double smoothing_velocity_m_s = 1e-4;     // v_eps of tanh(v / v_eps)
  bool encoder_on_carriage = false;         // false: on the motor shaft (q_m)
  double encoder_resolution_m = 0.0;        // 0: exact position
  double measurement_delay_s = 0.0;         // the position read this long after it was
  bool differenced_velocity = false;        // false: the exact velocity (of the sensed point)
  double velocity_filter_hz = 0.0;          // low-pass on the differenced velocity; 0: none
  double integration_step_s = 1.0e-5;

  std::string describe() const;  // one line: every size that differs from the nominal
};

// Every effect on, every size drawn uniformly from a plausible range (the ranges are in the .cpp,
// one line each); the same seed gives the same machine. Drive limits are the machine's rating,
// not drawn: 24 V and 40 N.
OffNominalParams draw_offnominal(uint64_t seed);

class OffNominalPlant final : public SampledPlant {
 public:
  explicit OffNominalPlant(const OffNominalParams& p);

  void reset(const Vec3& at_m) override;
  PlantState measure() const override { return measured_; }
  void advance(const Vec3& w_v, double period_s) override;
  Vec3 nozzle_m() const override;
  Vec3 nozzle_velocity_m_s() const override;
  bool limited() const override { return limited_; }

  const OffNominalParams& params() const { return p_; }

 private:
  // Per axis: motor-side position and velocity, current, carriage position and velocity.
  struct Axis {
    double qm = 0.0, vm = 0.0, i = 0.0, qc = 0.0, vc = 0.0;
  };
  struct AxisConst {
    double m_motor = 0.0;  // J_m / r^2 (rigid belt: plus the carriage)
    double m_carriage = 0.0;
    double b = 0.0;     // B / r^2
    double km_r = 0.0;  // K_m / r: N per A, and V per (m/s) of back-EMF
    double r_ohm = 0.0;
    double l_h = 0.0;
    double i_max = 0.0;  // 0: none
    double k_belt = 0.0, c_belt = 0.0;
    double gravity_n = 0.0;  // carriage weight (z)
  };
  Axis derivative(const Axis& s, const AxisConst& c, double v) const;
  double friction_n(double v) const;
  void clamp_current(Axis& s, const AxisConst& c) const;
  void step(double h, const Vec3& v);
  double sensed(size_t a) const;

  OffNominalParams p_;
  std::array<AxisConst, 3> c_{};
  std::array<Axis, 3> s_{};
  // Ring of the sensed positions at every substep, for the delay.
  static constexpr size_t kHistory = 4096;
  std::array<std::array<double, 3>, kHistory> history_{};
  std::array<std::array<double, 3>, kHistory> history_v_{};
  size_t head_ = 0;
  size_t delay_steps_ = 0;
  PlantState measured_{};
  Vec3 last_counts_m_ = Vec3::Zero();
  bool limited_ = false;
};

}  // namespace feedloop::maneuver
