// The delta paper's identification procedure (delta-lpv-receptance-coupling.txt, Sect. IV,
// Eq. 30-72) on a set of measurements; sim::simulate_measurements
// (sim/experiments/delta_measurements.hpp) simulates them with sim::DeltaPlant (rigid-body physics,
// not either force formula of the paper). docs/ident_delta.md has the whole story.
//
// Measurements (simulated: all small-signal FRFs of the simulator, i.e. the response a sine dwell
// converges to, on exact frequency grids):
//   Sect. IV-A  carriage A with the effector detached (one forearm left on: m = m_c + m_f/2,
//               Eq. 30), then again with m_add on the carriage (Eq. 37-41);
//   Sect. IV-B  impact test on the isolated effector (force to acceleration of m1, Eq. 45);
//               full-assembly FRFs at the centre for pure x, y and z translations
//               (q_i / X_j, nine FRFs, Eq. 65);
//   Sect. IV-C  full-assembly FRFs q / q_d at the centre and the three validation positions
//               (used only to score predictions, never to fit).
// Known without a dynamic test: m_f and m_tot = m1 + m2 (a scale), delta and D_e (the CAD model,
// Eq. 20), the geometry.
//
// Identification (identify):
//   1. carriage (Eq. 31-43): 4th-order rational fit of both carriage FRFs (Eq. 42); the pole pair
//      that moves with the added mass is mechanical, the other electrical; then one structured
//      least-squares fit of (omega_n, zeta, c/m, d0, d1, d2, omega_n') to both FRFs with k and
//      c + b shared (Eq. 36/40, 35/39); m from Eq. 41, k = m omega_n^2, c + b = 2 zeta omega_n m,
//      c = (c/m) m, b = (c + b) - c, m_c = m - m_f/2;
//   2. effector (Eq. 45-49): 2nd-order rational fit of the hammer FRF (Eq. 46), omega_z^2 = u0/u2,
//      omega_p^2 = v0, m1 = omega_z^2/omega_p^2 m_tot, m2 = m_tot - m1;
//   3. b_j, k_j (Eq. 66-69): least squares of the nine centre FRFs predicted by Eq. 29 (with the
//      chosen force transformation) against the measured ones; see docs for why this replaces the
//      paper's coefficient matching of Eq. 68.
// Validation (validate): Eq. 29 predictions at the four positions, mu_acc (Eq. 71) of the diagonal
// entries in magnitude and phase (Table II) and the error reduction against the measured centre
// FRF used everywhere (Eq. 72, Table III).
#pragma once

#include <array>
#include <complex>
#include <cstdint>
#include <vector>

#include <Eigen/Dense>

#include "core/result.hpp"
#include "model/delta_force.hpp"
#include "model/delta_params.hpp"
#include "model/frequency_grid.hpp"
#include "model/frf_set.hpp"
#include "model/lti.hpp"

namespace feedloop::ident::delta {

using Complex = std::complex<double>;

struct MeasurementPlan {
  Eigen::Vector3d centre_mm{0.0, 0.0, 30.0};
  std::array<Eigen::Vector3d, 3> validation_mm{Eigen::Vector3d{-80.0, 0.0, 30.0}, Eigen::Vector3d{40.0, -69.0, 30.0},
                                               Eigen::Vector3d{40.0, 69.0, 30.0}};
  model::FrequencyGrid carriage_grid{2.0, 300.0, 0.5};  // Sect. IV-A sweeps (the mode is near 125 Hz)
  model::FrequencyGrid hammer_grid{5.0, 400.0, 0.5};    // Sect. IV-B impact test
  model::FrequencyGrid centre_grid{2.0, 200.0, 0.5};    // Sect. IV-B x/y/z sweeps at the centre (m2 z mode ~175 Hz)
  model::FrequencyGrid validation_grid{};               // 2-125 Hz in 0.5 Hz steps (Eq. 71, n = 247)
  double m_add_kg = 0.2;                                // Eq. 41
  int hammer_axis = 2;                                  // x, y, z = 0, 1, 2
  // Measurement noise: every FRF point is multiplied by (1 + n), n complex Gaussian with
  // E|n|^2 = noise_rel^2 (0: exact small-signal FRFs).
  double noise_rel = 0.0;
  uint64_t seed = 1;
  // The detached effector: its forearms are given this (tiny) axial stiffness and no damping.
  double detached_arm_stiffness_n_m = 1e-6;
};

struct DeltaMeasurements {
  MeasurementPlan plan;
  std::vector<Complex> carriage;        // q_A / q_dA, effector detached, on carriage_grid
  std::vector<Complex> carriage_added;  // same with m_add on carriage A
  std::vector<Complex> hammer;          // s^2 X_1 / F_h (1/kg) along hammer_axis, on hammer_grid
  std::vector<Eigen::Matrix3cd> centre_task;  // (i, j) = q_i / X_j at the centre, on centre_grid
  model::FrfSet centre;                        // q / q_d at the centre, on validation_grid
  std::array<model::FrfSet, 3> validation;     // q / q_d at plan.validation_mm, on validation_grid
  // Known from a scale and the CAD model.
  double m_f_kg = 0.0;
  double m_tot_kg = 0.0;  // m1 + m2
  model::DeltaParams cad;  // delta_*, D_e, geometry, forearm_half_mass_on_m1 (other fields unused)
};

struct CarriageFit {
  model::TransferFunction g_qd;        // Eq. 42 rational fit (before the structured fit)
  model::TransferFunction g_qd_added;  // same with m_add
  double omega_n_rad_s = 0.0, zeta = 0.0;            // Eq. 33
  double omega_n_added_rad_s = 0.0, zeta_added = 0.0;  // Eq. 38
  double m_kg = 0.0, m_c_kg = 0.0, k_n_m = 0.0, c_n_s_m = 0.0, b_n_s_m = 0.0;
  double d0_per_s2 = 0.0, d1_per_s = 0.0, d2_per_s = 0.0;
  double rms_rel = 0.0;  // RMS of |G_fit / G_meas - 1| over both FRFs
};

struct EffectorFit {
  double omega_z_rad_s = 0.0, omega_p_rad_s = 0.0;  // Eq. 47-48
  double m1_kg = 0.0, m2_kg = 0.0;                  // Eq. 49
  double rms_rel = 0.0;                             // of the Eq. 46 fit
};

struct CouplingFit {
  Eigen::Vector3d b_n_s_m = Eigen::Vector3d::Zero();  // b_x, b_y, b_z
  Eigen::Vector3d k_n_m = Eigen::Vector3d::Zero();    // k_x, k_y, k_z
  // RMS over frequencies of ||H_pred - H_meas||_F / ||H_meas||_F (H: the nine centre FRFs
  // q_i / X_j): how well Eq. 29 with this force transformation explains the centre measurements.
  double rms_rel = 0.0;
  int evaluations = 0;
  // With free_mass_scale: the factor on the weighed m1, m2 that the centre data ask for (1 when
  // the force transformation distributes the effector's inertia as the machine does).
  double mass_scale = 1.0;
  bool physical = true;  // b_j > 0 and k_j > 0 (only the Eq. 68 route can fail this)
};

struct DeltaIdentification {
  model::ForceTransform form = model::ForceTransform::Paper;
  CarriageFit carriage;
  EffectorFit effector;
  CouplingFit coupling;
  model::DeltaParams params;  // Table I-like: everything the LPV model needs
};

Result<CarriageFit> identify_carriage(const DeltaMeasurements& meas);
Result<EffectorFit> identify_effector(const DeltaMeasurements& meas);
// b_j, k_j with every other parameter taken from `base`. free_mass_scale: also fit one factor on
// m1 and m2 (a diagnostic of the force transformation, not part of the procedure).
Result<CouplingFit> identify_coupling(const DeltaMeasurements& meas, const model::DeltaParams& base,
                                      model::ForceTransform form, bool free_mass_scale = false);
// The paper's own route for step 3, for comparison: each of the nine centre FRFs, electrical
// part divided out, fitted by Eq. 66 (3rd/4th order); the denominators matched to Eq. 68
// (expanded form) by linear least squares per axis j (carriages that do not move or feel no force
// along j, below 5 % of the column's largest, are skipped). alpha:
//   Published:          alpha_ji of Eq. 69 (force on carriage i per unit of w_j X_j);
//   PerCarriageMotion:  alpha_ji / (Jbar^-1)_ij (per unit of carriage i's own motion, which is what
//                       the single-carriage polynomial of Eq. 68 assumes; docs/ident_delta.md).
// A fit with b_j <= 0 or k_j <= 0 is returned with physical = false and rms_rel = inf.
enum class Eq68Alpha { Published, PerCarriageMotion };
Result<CouplingFit> identify_coupling_eq68(const DeltaMeasurements& meas, const model::DeltaParams& base,
                                           model::ForceTransform form, Eq68Alpha alpha);
// Steps 1-3.
Result<DeltaIdentification> identify(const DeltaMeasurements& meas, model::ForceTransform form);

// Tables II-III for one model. Column p of the 3x4 tables: 0 = centre, 1..3 = validation positions;
// rows = carriages A, B, C (diagonal entries i_i).
struct ValidationTables {
  Eigen::Matrix<double, 3, 4> acc_mag_pct, acc_phase_pct;  // Eq. 71
  Eigen::Matrix<double, 3, 3> reduction_mag_pct, reduction_phase_pct;  // Eq. 72, validation positions
  Eigen::Vector3d avg_acc_mag_pct, avg_acc_phase_pct;  // per carriage, over the four positions
};

Result<ValidationTables> validate(const DeltaMeasurements& meas, const model::DeltaParams& params,
                                  model::ForceTransform form);

}  // namespace feedloop::ident::delta
