// The delta printer in the time domain (delta-lpv-receptance-coupling.txt), as rigid-body
// physics rather than either force formula of the paper (DESIGN.md on Eq. 25/69):
//   - three carriages, each sub-model 1: mass m = m_c + m_f/2 on a belt (k, c) driven by the
//     motor position e, guide friction b (Eq. 30-33), where e follows the step command q_d
//     through the electrical dynamics G_qd,e = (d1 s + d0)/(s^2 + d2 s + d0) (Eq. 34,
//     non-minimum-phase: d1 < 0);
//   - six forearms (a parallelogram pair per carriage, ball joints) as axial springs of finite
//     stiffness between the carriage joints and the effector joints, with the FULL nonlinear
//     geometry (Eq. 3-5 are the arms' rest lengths, not a linearised Jacobian);
//   - the end-effector as a 6-DOF rigid body (nozzle holder m1 with its centre of mass at the
//     Table I offset delta from the joint centroid, and an inertia tensor) carrying the extruder
//     motor m2 on springs/dampers k_j, b_j along the task axes (Eq. 50-55), attached at the
//     centre of mass; gravity on every mass.
// The effector can tilt a little (the arms stretch), so its off-centre mass has a physical path
// to the carriages. With very stiff arms the linearisation tends to the virtual-work form of
// Eq. 29 (tests/sim/delta_frf_test.cpp).
//
// State (SI): per carriage [z, z', q, q'] with e = z + (d1/d0) z' (z = d0 xi of the electrical
// filter), then body centre of mass c (3), its velocity (3), rotation vector theta (3, small-angle
// kinematics dtheta/dt = omega; tilts stay below a milliradian), angular velocity omega (3, world
// frame), extruder motor position (3) and velocity (3): 30 states.
//
// Drivers start enabled. Owner: one thread. Carriage ports share one time line: calls must come in non-decreasing time
// across all three (an earlier time is applied at the current time and counted in late_events()).
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <memory>

#include <Eigen/Dense>

#include "core/result.hpp"
#include "drivers/device/motor_port.hpp"
#include "model/delta_params.hpp"
#include "sim/encoder.hpp"
#include "sim/linearize.hpp"

namespace feedloop::sim {

struct DeltaPlantParams {
  model::DeltaParams model;  // Table I parameters and the canonical geometry (shared with model/)
  double arm_stiffness_n_m = 1e7;         // axial stiffness of one forearm with its joints (arm modes 0.7-3 kHz)
  double arm_damping_n_s_m = 30.0;        // axial damping of one forearm
  double arm_pair_half_spacing_mm = 25.0;  // half the distance between the two arms of a pair
  Eigen::Vector3d effector_inertia_kg_m2{2.5e-4, 2.5e-4, 4.5e-4};  // m1 about its centre of mass
  double gravity_m_s2 = 9.81;
  double mm_per_step = 0.0125;            // 80 steps/mm (GT2 belt, 20-tooth pulley, 16 microsteps)
  Eigen::Vector3d initial_nozzle_mm{0.0, 0.0, 30.0};  // power-on position; steps and encoders zero here
  EncoderParams encoder;
  // Hard stops at the towers' tops (stall homing's reference), absolute carriage heights, mm; a
  // stiff contact (hard_stop_n_m, damped at zeta 0.5) above them. Infinite: none.
  std::array<double, 3> hard_stop_max_mm{std::numeric_limits<double>::infinity(),
                                         std::numeric_limits<double>::infinity(),
                                         std::numeric_limits<double>::infinity()};
  double hard_stop_n_m = 2.0e5;
  // Fixed RK4 step rate (step events split a substep at their exact time). 0: from the plant's
  // fastest mode (DeltaPlant::fastest_mode_rad_s, kRk4HOmegaMax in sim/linearize.hpp).
  double substep_hz = 0.0;
  uint64_t seed = 1;
};

Status validate(const DeltaPlantParams& p);

class DeltaPlant {
 public:
  static constexpr int kStates = 30;
  using State = Eigen::Matrix<double, kStates, 1>;

  // Finds the static equilibrium at the initial position (gravity sag included). Error for bad
  // parameters or an unreachable position.
  // With p.substep_hz = 0 the rate comes from fastest_mode_rad_s (substep_hz_for); params()
  // .substep_hz is the rate in use.
  static Result<std::unique_ptr<DeltaPlant>> create(const DeltaPlantParams& p);
  // The fastest mode of the linearised plant (rad/s) at its power-on equilibrium, times
  // kModeHeadroom for the rest of the workspace (the arm modes move with the arms' angles).
  double fastest_mode_rad_s() const;
  static constexpr double kModeHeadroom = 1.15;
  DeltaPlant(const DeltaPlant&) = delete;
  DeltaPlant& operator=(const DeltaPlant&) = delete;

  // The MotorPort of carriage i (0 = A, 1 = B, 2 = C); valid while the plant lives.
  device::MotorPort& carriage_port(int i) { return ports_[static_cast<size_t>(i)]; }

  void advance_to(double t_s);  // RT-safe

  // Ground truth.
  double time_s() const { return t_s_; }
  double carriage_mm(int i) const { return x_[4 * i + 2] * 1e3; }  // absolute carriage height
  bool motor_enabled(int i) const { return enabled_[static_cast<size_t>(i)]; }
  double carriage_rel_mm(int i) const { return (x_[4 * i + 2] - q0_m_[i]) * 1e3; }  // from power-on
  double commanded_rel_mm(int i) const { return static_cast<double>(steps_[static_cast<size_t>(i)]) * p_.mm_per_step; }
  Eigen::Vector3d nozzle_mm() const;
  Eigen::Vector3d tilt_rad() const { return x_.segment<3>(18); }
  int64_t late_events() const { return late_events_; }
  const DeltaPlantParams& params() const { return p_; }
  const State& state() const { return x_; }

  // The model: dx/dt for state x and commanded carriage positions qd (m, absolute).
  State derivative(const State& x, const Eigen::Vector3d& qd_m) const;
  // Small-signal model around the current state (at rest): inputs q_d (3), outputs q (3), SI.
  LinearModel linearize() const;

 private:
  class Port final : public device::MotorPort {
   public:
    Port() = default;
    Port(DeltaPlant* plant, int i) : plant_(plant), i_(i) {}
    void step(double t_s, int direction) override;
    void set_enabled(double t_s, bool enabled) override;
    int64_t read_encoder_counts(double t_s) override;
    bool read_encoder_index(double t_s) override;

   private:
    DeltaPlant* plant_ = nullptr;
    int i_ = 0;
  };

  // derivative()'s coefficients, derived once from the parameters (SI; reciprocals where the
  // model divides): the hot loop reads them from one flat block.
  struct Coeffs {
    double m = 0.0, inv_m = 0.0, inv_m1 = 0.0, m2 = 0.0, inv_m2 = 0.0, g = 0.0;
    double d0 = 0.0, d1_over_d0 = 0.0, d2 = 0.0, k = 0.0, c = 0.0, b = 0.0;  // carriage (Eq. 30-34)
    double arm_k = 0.0, arm_c = 0.0, arm_len = 0.0, inv_arm_len = 0.0, inv_arm_len2 = 0.0;
    std::array<double, 3> kj{}, bj{}, inertia{}, inv_inertia{};
    // Per forearm a (on carriage a / 2), component-major ([x|y|z][a]): its effector joint from the
    // centre of mass in the body frame, and its carriage joint at q = 0.
    double joint_body[3][6] = {}, joint_carriage[3][6] = {};
  };

  explicit DeltaPlant(const DeltaPlantParams& p);
  void derive_(const double* x, const double* qd_m, double* d) const;
  Status settle_static_();
  void integrate_(double h);
  Eigen::Vector3d qd_m_() const;
  void sync_(double t_s);

  DeltaPlantParams p_;
  std::array<Port, 3> ports_;
  std::array<LinearEncoder, 3> encoders_;
  std::array<History, 3> history_;
  State x_ = State::Zero();
  double t_s_ = 0.0;
  std::array<int64_t, 3> steps_{0, 0, 0};
  std::array<bool, 3> enabled_{true, true, true};
  Eigen::Vector3d q0_m_ = Eigen::Vector3d::Zero();   // carriage positions at power-on (encoder zero)
  Eigen::Vector3d qd0_m_ = Eigen::Vector3d::Zero();  // commanded positions at power-on (step zero)
  int64_t late_events_ = 0;
  double h_s_ = 0.0;
  Coeffs k_;
};

}  // namespace feedloop::sim
