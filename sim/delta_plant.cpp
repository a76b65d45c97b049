// Time-domain delta plant: arm forces, rigid-body effector, carriages, static equilibrium and
// linearisation (see delta_plant.hpp for the model).
#include "sim/delta_plant.hpp"

#include <cmath>

#include "model/delta_kinematics.hpp"

namespace feedloop::sim {

namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr double kTimeEps_s = 1e-12;
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
  if (p.substep_hz < 1000.0 || p.substep_hz > 1e7) return Error{"substep_hz must be in [1 kHz, 10 MHz]", {}};
  return Status::Ok();
}

Result<std::unique_ptr<DeltaPlant>> DeltaPlant::create(const DeltaPlantParams& p) {
  if (Status s = validate(p); !s) return Error{"delta plant: " + s.error().message, s.error().where};
  std::unique_ptr<DeltaPlant> plant(new DeltaPlant(p));
  if (Status s = plant->settle_static_(); !s) return s.error();
  return plant;
}

DeltaPlant::DeltaPlant(const DeltaPlantParams& p)
    : p_(p),
      ports_{Port(this, 0), Port(this, 1), Port(this, 2)},
      encoders_{LinearEncoder(p.encoder, p.seed), LinearEncoder(p.encoder, p.seed + 1),
                LinearEncoder(p.encoder, p.seed + 2)},
      history_{History(history_capacity(p)), History(history_capacity(p)), History(history_capacity(p))},
      h_s_(1.0 / p.substep_hz) {}

DeltaPlant::State DeltaPlant::derivative(const State& x, const Eigen::Vector3d& qd_m) const {
  const model::DeltaParams& mp = p_.model;
  const double g = p_.gravity_m_s2;
  const double m = mp.m_kg(), m1 = mp.m1_effective_kg(), m2 = mp.m2_kg;
  const double r_m = mp.geometry.radius_mm * 1e-3, de_m = mp.D_e_mm * 1e-3;
  const double len_m = mp.geometry.arm_length_mm * 1e-3, w_m = p_.arm_pair_half_spacing_mm * 1e-3;
  const Eigen::Vector3d delta_m(mp.delta_x_mm * 1e-3, mp.delta_y_mm * 1e-3, mp.delta_z_mm * 1e-3);

  const Eigen::Vector3d c = x.segment<3>(kC), v = x.segment<3>(kV), om = x.segment<3>(kW);
  const Eigen::Matrix3d rot = rotation(x.segment<3>(kTh));
  State d = State::Zero();

  Eigen::Vector3d force = Eigen::Vector3d::Zero(), torque = Eigen::Vector3d::Zero();
  for (int i = 0; i < 3; ++i) {
    // Carriage i: electrical filter (Eq. 34) -> motor position e, belt and guide (Eq. 32).
    const double z = x[4 * i], zd = x[4 * i + 1], q = x[4 * i + 2], qdot = x[4 * i + 3];
    const double zdd = mp.d0_per_s2 * (qd_m[i] - z) - mp.d2_per_s * zd;
    double f_carriage = -mp.b_n_s_m * qdot - m * g;
    if (enabled_[static_cast<size_t>(i)]) {
      const double e = z + mp.d1_per_s / mp.d0_per_s2 * zd;
      const double edot = zd + mp.d1_per_s / mp.d0_per_s2 * zdd;
      f_carriage += mp.k_n_m * (e - q) + mp.c_n_s_m * (edot - qdot);
    }
    // Its two forearms: axial springs between the ball joints (Eq. 3-5 hold at rest length).
    const double phi = mp.geometry.tower_angle_deg[static_cast<size_t>(i)] * kPi / 180.0;
    const Eigen::Vector3d radial(std::cos(phi), std::sin(phi), 0.0), tangent(-std::sin(phi), std::cos(phi), 0.0);
    for (const double side : {-1.0, 1.0}) {
      const Eigen::Vector3d joint_body = de_m * radial + side * w_m * tangent - delta_m;  // from the COM
      const Eigen::Vector3d arm_r = rot * joint_body;
      const Eigen::Vector3d p_joint = c + arm_r;
      const Eigen::Vector3d v_joint = v + om.cross(arm_r);
      const Eigen::Vector3d c_joint = (r_m + de_m) * radial + side * w_m * tangent + Eigen::Vector3d(0, 0, q);
      const Eigen::Vector3d c_vel(0.0, 0.0, qdot);
      const Eigen::Vector3d dvec = c_joint - p_joint;
      const double l = dvec.norm();
      const Eigen::Vector3d n = dvec / l;
      const double tension = p_.arm_stiffness_n_m * (l - len_m) + p_.arm_damping_n_s_m * n.dot(c_vel - v_joint);
      force += tension * n;
      torque += arm_r.cross(tension * n);
      f_carriage -= tension * n.z();
    }
    d[4 * i] = zd;
    d[4 * i + 1] = zdd;
    d[4 * i + 2] = qdot;
    d[4 * i + 3] = f_carriage / m;
  }
  // Extruder motor m2 on k_j, b_j (Eq. 50-55), attached at the centre of mass.
  const Eigen::Vector3d kj(mp.k_x_n_m, mp.k_y_n_m, mp.k_z_n_m), bj(mp.b_x_n_s_m, mp.b_y_n_s_m, mp.b_z_n_s_m);
  const Eigen::Vector3d gvec(0.0, 0.0, -g);
  Eigen::Vector3d f_m2 = Eigen::Vector3d::Zero();  // on m2
  if (m2 > 0.0) {
    f_m2 = -kj.cwiseProduct(x.segment<3>(kX2) - c) - bj.cwiseProduct(x.segment<3>(kV2) - v);
    d.segment<3>(kX2) = x.segment<3>(kV2);
    d.segment<3>(kV2) = f_m2 / m2 + gvec;
  }
  d.segment<3>(kC) = v;
  d.segment<3>(kV) = (force - f_m2) / m1 + gvec;
  // Rigid-body rotation: I_w omega' = tau - omega x I_w omega (Euler, world frame).
  const Eigen::Matrix3d inertia = rot * p_.effector_inertia_kg_m2.asDiagonal() * rot.transpose();
  const Eigen::Matrix3d inertia_inv = rot * p_.effector_inertia_kg_m2.cwiseInverse().asDiagonal() * rot.transpose();
  d.segment<3>(kTh) = om;
  d.segment<3>(kW) = inertia_inv * (torque - om.cross(inertia * om));
  return d;
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
