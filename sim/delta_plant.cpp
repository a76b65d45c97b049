// Time-domain delta plant: arm forces, rigid-body effector, carriages, static equilibrium and
// linearisation (see delta_plant.hpp for the model).
#include "sim/delta_plant.hpp"

#include <cmath>

#include "model/delta_kinematics.hpp"

namespace feedloop::sim {

namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr double kTimeEps_s = 1e-12;
// The arm-length series in derive_ holds to rounding up to this strain of the squared length.
constexpr double kArmSeriesMaxEps = 1e-3;
constexpr int kC = 12, kV = 15, kTh = 18, kW = 21, kX2 = 24, kV2 = 27;  // state offsets

Eigen::Matrix3d rotation(const Eigen::Vector3d& theta) {
  const double a = theta.norm();
  if (a < 1e-15) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(a, theta / a).toRotationMatrix();
}

size_t history_capacity(const DeltaPlantParams& p) {
  return static_cast<size_t>(std::ceil(p.encoder.sampling_delay_s * p.substep_hz * 2.0)) + 8;
}
}  // namespace

Status validate(const DeltaPlantParams& p) {
  if (Status s = model::validate(p.model); !s) return s;
  if (Status s = validate(p.encoder); !s) return s;
  if (!(p.arm_stiffness_n_m > 0.0)) return Error{"arm_stiffness_n_m must be > 0", {}};
  if (!(p.arm_damping_n_s_m >= 0.0)) return Error{"arm_damping_n_s_m must be >= 0", {}};
  if (!(p.arm_pair_half_spacing_mm > 0.0)) return Error{"arm_pair_half_spacing_mm must be > 0", {}};
  if (!(p.effector_inertia_kg_m2.minCoeff() > 0.0)) return Error{"effector_inertia_kg_m2 must be > 0", {}};
  if (!(p.mm_per_step > 0.0)) return Error{"mm_per_step must be > 0", {}};
  if (!(p.gravity_m_s2 >= 0.0)) return Error{"gravity_m_s2 must be >= 0", {}};
  if (p.substep_hz != 0.0 && !(p.substep_hz >= 1000.0 && p.substep_hz <= 1e7))
    return Error{"substep_hz must be 0 (from the fastest mode) or in [1 kHz, 10 MHz]", {}};
  return Status::Ok();
}

Result<std::unique_ptr<DeltaPlant>> DeltaPlant::create(const DeltaPlantParams& p) {
  if (Status s = validate(p); !s) return Error{"delta plant: " + s.error().message, s.error().where};
  std::unique_ptr<DeltaPlant> plant(new DeltaPlant(p));
  if (Status s = plant->settle_static_(); !s) return s.error();
  if (p.substep_hz == 0.0) {
    const double hz = substep_hz_for(plant->fastest_mode_rad_s());
    if (hz > 1e7) return Error{"delta plant: fastest mode above 10 MHz: set substep_hz", {}};
    plant->p_.substep_hz = hz;
    plant->h_s_ = 1.0 / hz;
    // The history holds the samples of the delay at the new rate.
    for (int i = 0; i < 3; ++i) {
      History& h = plant->history_[static_cast<size_t>(i)];
      h = History(history_capacity(plant->p_));
      h.clear(0.0, plant->x_[4 * i + 2]);
    }
  }
  return plant;
}

DeltaPlant::DeltaPlant(const DeltaPlantParams& p)
    : p_(p),
      ports_{Port(this, 0), Port(this, 1), Port(this, 2)},
      encoders_{LinearEncoder(p.encoder, p.seed), LinearEncoder(p.encoder, p.seed + 1),
                LinearEncoder(p.encoder, p.seed + 2)},
      history_{History(history_capacity(p)), History(history_capacity(p)),
               History(history_capacity(p))},
      h_s_(1.0 / p.substep_hz) {
  const model::DeltaParams& mp = p.model;
  k_.m = mp.m_kg();
  k_.inv_m = 1.0 / k_.m;
  k_.inv_m1 = 1.0 / mp.m1_effective_kg();
  k_.m2 = mp.m2_kg;
  k_.inv_m2 = mp.m2_kg > 0.0 ? 1.0 / mp.m2_kg : 0.0;
  k_.g = p.gravity_m_s2;
  k_.d0 = mp.d0_per_s2;
  k_.d1_over_d0 = mp.d1_per_s / mp.d0_per_s2;
  k_.d2 = mp.d2_per_s;
  k_.k = mp.k_n_m;
  k_.c = mp.c_n_s_m;
  k_.b = mp.b_n_s_m;
  k_.arm_k = p.arm_stiffness_n_m;
  k_.arm_c = p.arm_damping_n_s_m;
  k_.arm_len = mp.geometry.arm_length_mm * 1e-3;
  k_.inv_arm_len = 1.0 / k_.arm_len;
  k_.inv_arm_len2 = k_.inv_arm_len * k_.inv_arm_len;
  k_.kj = {mp.k_x_n_m, mp.k_y_n_m, mp.k_z_n_m};
  k_.bj = {mp.b_x_n_s_m, mp.b_y_n_s_m, mp.b_z_n_s_m};
  for (int j = 0; j < 3; ++j) {
    k_.inertia[static_cast<size_t>(j)] = p.effector_inertia_kg_m2[j];
    k_.inv_inertia[static_cast<size_t>(j)] = 1.0 / p.effector_inertia_kg_m2[j];
  }
  const double r_m = mp.geometry.radius_mm * 1e-3, de_m = mp.D_e_mm * 1e-3;
  const double w_m = p.arm_pair_half_spacing_mm * 1e-3;
  const Eigen::Vector3d delta_m(mp.delta_x_mm * 1e-3, mp.delta_y_mm * 1e-3, mp.delta_z_mm * 1e-3);
  for (int i = 0; i < 3; ++i) {
    // Carriage i's two forearms, at +/- w tangentially (Eq. 3-5 hold at rest length).
    const double phi = mp.geometry.tower_angle_deg[static_cast<size_t>(i)] * kPi / 180.0;
    const Eigen::Vector3d radial(std::cos(phi), std::sin(phi), 0.0),
        tangent(-std::sin(phi), std::cos(phi), 0.0);
    for (int side = 0; side < 2; ++side) {
      const double sgn = side == 0 ? -1.0 : 1.0;
      const Eigen::Vector3d jb = de_m * radial + sgn * w_m * tangent - delta_m;  // from the COM
      const Eigen::Vector3d jc = (r_m + de_m) * radial + sgn * w_m * tangent;
      const auto a = static_cast<size_t>(2 * i + side);
      for (int j = 0; j < 3; ++j) {
        k_.joint_body[static_cast<size_t>(j)][a] = jb[j];
        k_.joint_carriage[static_cast<size_t>(j)][a] = jc[j];
      }
    }
  }
}

DeltaPlant::State DeltaPlant::derivative(const State& x, const Eigen::Vector3d& qd_m) const {
  State d;
  derive_(x.data(), qd_m.data(), d.data());
  return d;
}

// The model on flat arrays (x, d: kStates; qd_m: 3), written out component by component: RK4
// calls it four times a substep, and the Eigen expression of the same equations (3x3 products
// for the inertia in the world frame, an angle-axis rotation, the arm geometry from the tower
// angles) spent most of the plant's time building temporaries.
void DeltaPlant::derive_(const double* x, const double* qd_m, double* d) const {
  const Coeffs& k = k_;
  const double* c = x + kC;
  const double* v = x + kV;
  const double* th = x + kTh;
  const double* om = x + kW;
  // Rotation matrix of theta (Rodrigues): R = cos a I + (sin a / a) [theta]x + ((1 - cos a) / a^2)
  // theta theta^T. Tilts are ~1e-5 rad: below a = 1e-3 the series (first omitted term a^6 / 720)
  // are exact to rounding and need no trigonometry.
  const double a2 = th[0] * th[0] + th[1] * th[1] + th[2] * th[2];
  double ca, sa, oa;  // cos a, sin a / a, (1 - cos a) / a^2
  if (a2 < 1e-6) {
    ca = 1.0 - a2 * 0.5 * (1.0 - a2 * (1.0 / 12.0));  // products, not quotients (no -ffast-math)
    sa = 1.0 - a2 * (1.0 / 6.0) * (1.0 - a2 * (1.0 / 20.0));
    oa = 0.5 - a2 * (1.0 / 24.0) * (1.0 - a2 * (1.0 / 30.0));
  } else {
    const double a = std::sqrt(a2);
    ca = std::cos(a);
    sa = std::sin(a) / a;
    oa = (1.0 - ca) / a2;
  }
  double rot[3][3];
  for (int r = 0; r < 3; ++r)
    for (int s = 0; s < 3; ++s) rot[r][s] = oa * th[r] * th[s] + (r == s ? ca : 0.0);
  rot[0][1] -= sa * th[2];
  rot[1][0] += sa * th[2];
  rot[0][2] += sa * th[1];
  rot[2][0] -= sa * th[1];
  rot[1][2] -= sa * th[0];
  rot[2][1] += sa * th[0];

  // The six forearms (a parallelogram pair per carriage; arm a on carriage a / 2): axial springs
  // between the ball joints. Component by component over the six arms (flat arrays of 6), so that
  // the compiler runs two arms per SIMD instruction where the target has them.
  constexpr int kArms = 6;
  double q[kArms], qdot[kArms];
  for (int a = 0; a < kArms; ++a) {
    q[a] = x[4 * (a / 2) + 2];
    qdot[a] = x[4 * (a / 2) + 3];
  }
  double arm_r[3][kArms], dvec[3][kArms];
  for (int r = 0; r < 3; ++r)
    for (int a = 0; a < kArms; ++a)
      arm_r[r][a] = rot[r][0] * k.joint_body[0][a] + rot[r][1] * k.joint_body[1][a] +
                    rot[r][2] * k.joint_body[2][a];
  for (int a = 0; a < kArms; ++a) {
    dvec[0][a] = k.joint_carriage[0][a] - (c[0] + arm_r[0][a]);
    dvec[1][a] = k.joint_carriage[1][a] - (c[1] + arm_r[1][a]);
    dvec[2][a] = k.joint_carriage[2][a] + q[a] - (c[2] + arm_r[2][a]);
  }
  // Arm length l and 1 / l. A forearm stretches by microns, so l^2 / L^2 = 1 + eps with |eps| ~
  // 1e-5: there sqrt(1 + eps) and its reciprocal by their series (first omitted terms below 3e-17
  // for |eps| < 1e-3) replace a square root and a division, and give the stretch l - L without
  // cancellation. Any arm beyond that (a violent transient) takes the exact form.
  double eps[kArms], stretch[kArms], inv_l[kArms];
  bool series_ok = true;
  for (int a = 0; a < kArms; ++a) {
    const double e = (dvec[0][a] * dvec[0][a] + dvec[1][a] * dvec[1][a] + dvec[2][a] * dvec[2][a]) *
                         k.inv_arm_len2 -
                     1.0;
    eps[a] = e;
    stretch[a] = k.arm_len * e * (0.5 - e * (0.125 - e * (0.0625 - e * (5.0 / 128.0))));
    inv_l[a] = k.inv_arm_len * (1.0 - e * (0.5 - e * (0.375 - e * (0.3125 - e * (35.0 / 128.0)))));
    series_ok = series_ok && std::abs(e) < kArmSeriesMaxEps;
  }
  if (!series_ok)
    for (int a = 0; a < kArms; ++a) {
      const double l = k.arm_len * std::sqrt(1.0 + eps[a]);
      stretch[a] = l - k.arm_len;
      inv_l[a] = 1.0 / l;
    }
  // Tension: spring plus damping on the stretch rate n . (carriage joint velocity (0, 0, qdot) -
  // effector joint velocity v + omega x r), where n . (omega x r) = omega . (r x n); the same
  // r x n gives the arm's torque on the effector, tension (r x n).
  double fz[kArms];
  double force[3] = {0.0, 0.0, 0.0}, torque[3] = {0.0, 0.0, 0.0};
  for (int a = 0; a < kArms; ++a) {
    const double n0 = dvec[0][a] * inv_l[a], n1 = dvec[1][a] * inv_l[a], n2 = dvec[2][a] * inv_l[a];
    const double rn0 = arm_r[1][a] * n2 - arm_r[2][a] * n1;
    const double rn1 = arm_r[2][a] * n0 - arm_r[0][a] * n2;
    const double rn2 = arm_r[0][a] * n1 - arm_r[1][a] * n0;
    const double stretch_rate = n2 * qdot[a] - (n0 * v[0] + n1 * v[1] + n2 * v[2]) -
                                (om[0] * rn0 + om[1] * rn1 + om[2] * rn2);
    const double tension = k.arm_k * stretch[a] + k.arm_c * stretch_rate;
    force[0] += tension * n0;
    force[1] += tension * n1;
    force[2] += tension * n2;
    torque[0] += tension * rn0;
    torque[1] += tension * rn1;
    torque[2] += tension * rn2;
    fz[a] = tension * n2;
  }

  for (int i = 0; i < 3; ++i) {
    // Carriage i: electrical filter (Eq. 34) -> motor position e, belt and guide (Eq. 32), and
    // its two forearms.
    const double z = x[4 * i], zd = x[4 * i + 1], qi = x[4 * i + 2], qdi = x[4 * i + 3];
    const double zdd = k.d0 * (qd_m[i] - z) - k.d2 * zd;
    double f_carriage = -k.b * qdi - k.m * k.g - fz[2 * i] - fz[2 * i + 1];
    // The hard stop at the tower's top (stall homing): a stiff contact above it.
    if (const double stop_m = p_.hard_stop_max_mm[static_cast<size_t>(i)] * 1e-3; qi > stop_m)
      f_carriage -= p_.hard_stop_n_m * (qi - stop_m) + std::sqrt(p_.hard_stop_n_m * k.m) * qdi;
    if (enabled_[static_cast<size_t>(i)]) {
      const double e = z + k.d1_over_d0 * zd;
      const double edot = zd + k.d1_over_d0 * zdd;
      f_carriage += k.k * (e - qi) + k.c * (edot - qdi);
    }
    d[4 * i] = zd;
    d[4 * i + 1] = zdd;
    d[4 * i + 2] = qdi;
    d[4 * i + 3] = f_carriage * k.inv_m;
  }
  // Extruder motor m2 on k_j, b_j (Eq. 50-55), attached at the centre of mass.
  double f_m2[3] = {0.0, 0.0, 0.0};  // on m2
  for (int j = 0; j < 3; ++j) {
    const auto js = static_cast<size_t>(j);
    if (k.m2 > 0.0) {
      f_m2[j] = -k.kj[js] * (x[kX2 + j] - c[j]) - k.bj[js] * (x[kV2 + j] - v[j]);
      d[kX2 + j] = x[kV2 + j];
      d[kV2 + j] = f_m2[j] * k.inv_m2 - (j == 2 ? k.g : 0.0);
    } else {
      d[kX2 + j] = d[kV2 + j] = 0.0;
    }
    d[kC + j] = v[j];
    d[kV + j] = (force[j] - f_m2[j]) * k.inv_m1 - (j == 2 ? k.g : 0.0);
    d[kTh + j] = om[j];
  }
  // Rigid-body rotation: I_w omega' = tau - omega x I_w omega (Euler, world frame), with
  // I_w = R I R^T applied as R (I (R^T w)) instead of forming the world-frame tensors.
  double ob[3], hw[3], rhs[3], rb[3];
  for (int j = 0; j < 3; ++j)
    ob[j] = rot[0][j] * om[0] + rot[1][j] * om[1] + rot[2][j] * om[2];  // R^T omega
  for (int r = 0; r < 3; ++r)
    hw[r] = rot[r][0] * k.inertia[0] * ob[0] + rot[r][1] * k.inertia[1] * ob[1] +
            rot[r][2] * k.inertia[2] * ob[2];
  rhs[0] = torque[0] - (om[1] * hw[2] - om[2] * hw[1]);
  rhs[1] = torque[1] - (om[2] * hw[0] - om[0] * hw[2]);
  rhs[2] = torque[2] - (om[0] * hw[1] - om[1] * hw[0]);
  for (int j = 0; j < 3; ++j)
    rb[j] = (rot[0][j] * rhs[0] + rot[1][j] * rhs[1] + rot[2][j] * rhs[2]) *
            k.inv_inertia[static_cast<size_t>(j)];
  for (int r = 0; r < 3; ++r) d[kW + r] = rot[r][0] * rb[0] + rot[r][1] * rb[1] + rot[r][2] * rb[2];
}

Eigen::Vector3d DeltaPlant::qd_m_() const {
  Eigen::Vector3d qd;
  for (int i = 0; i < 3; ++i) qd[i] = qd0_m_[i] + static_cast<double>(steps_[static_cast<size_t>(i)]) * p_.mm_per_step * 1e-3;
  return qd;
}

Status DeltaPlant::settle_static_() {
  const model::DeltaParams& mp = p_.model;
  Result<Eigen::Vector3d> q_mm = model::inverse_kinematics(mp.geometry, p_.initial_nozzle_mm);
  if (!q_mm.ok()) return Error{"delta plant: initial position: " + q_mm.error().message, {}};
  qd0_m_ = *q_mm * 1e-3;
  const Eigen::Vector3d delta_m(mp.delta_x_mm * 1e-3, mp.delta_y_mm * 1e-3, mp.delta_z_mm * 1e-3);
  const Eigen::Vector3d centroid = p_.initial_nozzle_mm * 1e-3 + Eigen::Vector3d(0, 0, mp.geometry.nozzle_offset_mm * 1e-3);
  x_.setZero();
  for (int i = 0; i < 3; ++i) x_[4 * i] = x_[4 * i + 2] = qd0_m_[i];
  x_.segment<3>(kC) = centroid + delta_m;
  x_.segment<3>(kX2) = centroid + delta_m;
  // Newton on the 12 positions (q, c, theta, x2) so that every acceleration vanishes; the
  // electrical states stay at z = q_d (its static gain is 1). Gravity stretches belts and arms.
  const int pos_idx[12] = {2, 6, 10, kC, kC + 1, kC + 2, kTh, kTh + 1, kTh + 2, kX2, kX2 + 1, kX2 + 2};
  const int acc_idx[12] = {3, 7, 11, kV, kV + 1, kV + 2, kW, kW + 1, kW + 2, kV2, kV2 + 1, kV2 + 2};
  const Eigen::Vector3d qd = qd_m_();
  auto residual = [&](const State& s) {
    const State dd = derivative(s, qd);
    Eigen::Matrix<double, 12, 1> r;
    for (int k = 0; k < 12; ++k) r[k] = dd[acc_idx[k]];
    return r;
  };
  // Converged when the residual accelerations are at the rounding level of the stiffest spring.
  const double tol_m_s2 = 1e-9 * (1.0 + p_.arm_stiffness_n_m / mp.m1_effective_kg());
  for (int it = 0; it < 30; ++it) {
    const Eigen::Matrix<double, 12, 1> r0 = residual(x_);
    if (r0.norm() < tol_m_s2) break;
    Eigen::Matrix<double, 12, 12> jac;
    for (int k = 0; k < 12; ++k) {
      State xp = x_, xm = x_;
      xp[pos_idx[k]] += 1e-9;
      xm[pos_idx[k]] -= 1e-9;
      jac.col(k) = (residual(xp) - residual(xm)) / 2e-9;
    }
    const Eigen::Matrix<double, 12, 1> step = jac.fullPivLu().solve(r0);
    for (int k = 0; k < 12; ++k) x_[pos_idx[k]] -= step[k];
  }
  if (residual(x_).norm() > 10.0 * tol_m_s2) return Error{"delta plant: no static equilibrium at the initial position", {}};
  for (int i = 0; i < 3; ++i) {
    q0_m_[i] = x_[4 * i + 2];
    history_[static_cast<size_t>(i)].clear(0.0, x_[4 * i + 2]);
  }
  return Status::Ok();
}

double DeltaPlant::fastest_mode_rad_s() const {
  return kModeHeadroom * sim::fastest_mode_rad_s(linearize().a);
}

void DeltaPlant::integrate_(double h) {
  const Eigen::Vector3d qd = qd_m_();
  const State k1 = derivative(x_, qd);
  const State k2 = derivative(x_ + 0.5 * h * k1, qd);
  const State k3 = derivative(x_ + 0.5 * h * k2, qd);
  const State k4 = derivative(x_ + h * k3, qd);
  x_ += (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
}

void DeltaPlant::advance_to(double t_s) {
  while (t_s - t_s_ > kTimeEps_s) {
    const double h = std::min(h_s_, t_s - t_s_);
    integrate_(h);
    t_s_ = (t_s - t_s_ - h <= kTimeEps_s) ? t_s : t_s_ + h;
    if (p_.encoder.sampling_delay_s > 0.0)
      for (int i = 0; i < 3; ++i) history_[static_cast<size_t>(i)].push(t_s_, x_[4 * i + 2]);
  }
}

void DeltaPlant::sync_(double t_s) {
  if (t_s < t_s_) ++late_events_;
  advance_to(t_s);
}

Eigen::Vector3d DeltaPlant::nozzle_mm() const {
  const model::DeltaParams& mp = p_.model;
  const Eigen::Vector3d delta_m(mp.delta_x_mm * 1e-3, mp.delta_y_mm * 1e-3, mp.delta_z_mm * 1e-3);
  const Eigen::Matrix3d rot = rotation(x_.segment<3>(kTh));
  return (x_.segment<3>(kC) + rot * (Eigen::Vector3d(0, 0, -mp.geometry.nozzle_offset_mm * 1e-3) - delta_m)) * 1e3;
}

void DeltaPlant::Port::step(double t_s, int direction) {
  plant_->sync_(t_s);
  plant_->steps_[static_cast<size_t>(i_)] += direction >= 0 ? 1 : -1;
}

void DeltaPlant::Port::set_enabled(double t_s, bool enabled) {
  plant_->sync_(t_s);
  plant_->enabled_[static_cast<size_t>(i_)] = enabled;
}

bool DeltaPlant::Port::read_encoder_index(double t_s) {
  const double period_mm = plant_->p_.encoder.index_period_mm;
  if (!(period_mm > 0.0)) return false;
  plant_->sync_(t_s);
  const auto i = static_cast<size_t>(i_);
  const double q =
      plant_->p_.encoder.sampling_delay_s > 0.0
          ? plant_->history_[i].value_at(plant_->t_s_ - plant_->p_.encoder.sampling_delay_s)
          : plant_->x_[4 * i_ + 2];
  // The marks at odd multiples of half a period of the carriage's absolute height (encoder.hpp).
  const double from_mark_mm = q * 1e3 - 0.5 * period_mm;
  return from_mark_mm - std::floor(from_mark_mm / period_mm) * period_mm <
         plant_->encoders_[i].mm_per_count();
}

int64_t DeltaPlant::Port::read_encoder_counts(double t_s) {
  plant_->sync_(t_s);
  const auto i = static_cast<size_t>(i_);
  const double q = plant_->p_.encoder.sampling_delay_s > 0.0
                       ? plant_->history_[i].value_at(plant_->t_s_ - plant_->p_.encoder.sampling_delay_s)
                       : plant_->x_[4 * i_ + 2];
  return plant_->encoders_[i].counts((q - plant_->q0_m_[i_]) * 1e3);
}

LinearModel DeltaPlant::linearize() const {
  Dynamics f = [this](const Eigen::VectorXd& x, const Eigen::VectorXd& u) -> Eigen::VectorXd {
    return derivative(State(x), Eigen::Vector3d(u));
  };
  Eigen::VectorXd dx = Eigen::VectorXd::Constant(kStates, 1e-9);
  for (int i = 0; i < 3; ++i) dx[4 * i + 1] = dx[4 * i + 3] = 1e-6;
  dx.segment<3>(kV).setConstant(1e-6);
  dx.segment<3>(kTh).setConstant(1e-8);
  dx.segment<3>(kW).setConstant(1e-5);
  dx.segment<3>(kV2).setConstant(1e-6);
  Eigen::MatrixXd c = Eigen::MatrixXd::Zero(3, kStates);
  for (int i = 0; i < 3; ++i) c(i, 4 * i + 2) = 1.0;
  return linearize_dynamics(f, Eigen::VectorXd(x_), Eigen::VectorXd(qd_m_()), dx, 1e-9, c);
}

}  // namespace feedloop::sim
