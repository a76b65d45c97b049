// One axis of the second simulator (see axis2.hpp and docs/plant2.md).
#include "plant2/axis2.hpp"

#include <algorithm>
#include <cmath>

namespace feedloop::plant2 {

namespace {

constexpr double kPi = 3.141592653589793;
constexpr double kTwoPi = 6.283185307179586;
// Width of the smooth switch of the direction-dependent stiffness (thesis Eq. 6's sgn(-r theta -
// x_2), smoothed over a micrometre so that the force stays continuous).
constexpr double kDirectionSwitchM = 1e-6;
// The step rule's factor: semi-implicit Euler is stable for omega dt < 2 (undamped); with the
// Gershgorin bound's omega + gamma this keeps the fastest mode at omega dt <= 1.5.
constexpr double kStepFactor = 1.5;

LuGreParams lugre_of(const CarriageParams& c) {
  LuGreParams l;
  l.coulomb_n = c.coulomb_n;
  l.static_n = std::max(c.static_n, c.coulomb_n);
  l.stribeck_m_s = c.stribeck_m_s;
  l.sigma0_n_m = c.bristle_stiffness_n_m;
  l.sigma1_n_s_m = c.bristle_damping_n_s_m > 0.0
                       ? c.bristle_damping_n_s_m
                       : 0.3 * 2.0 * std::sqrt(c.bristle_stiffness_n_m * c.mass_kg);
  l.sigma2_n_s_m = c.viscous_n_s_m;
  return l;
}

}  // namespace

Axis2::Axis2(const Axis2Params& p)
    : params_(p), friction_(lugre_of(p.carriage)), encoder_(p.encoder, p.start_m, 1e-5) {}

void Axis2::span_lengths(const BeltParams& b, double x_m, double out_m[3]) {
  out_m[0] = std::max(b.min_span_m, b.pulley_gap_m + x_m);
  out_m[1] = std::max(b.min_span_m, b.travel_m + b.end_gap_m - x_m);
  out_m[2] = b.pulley_gap_m + b.travel_m + b.end_gap_m;
}

double Axis2::belt_stiffness_n_m(const BeltParams& b, double x_m) {
  double l[3];
  span_lengths(b, x_m, l);
  return b.specific_stiffness_n / l[0] + b.specific_stiffness_n / (l[1] + l[2]);
}

Result<Axis2> Axis2::create(const Axis2Params& p) {
  if (Status s = validate(p); !s) return s.error();
  Axis2 a(p);
  const StepperParams& st = p.stepper;
  const BeltParams& b = p.belt;
  const CarriageParams& c = p.carriage;
  a.n_ = b.segments_per_span;
  a.ring_ = static_cast<size_t>(3 * a.n_);
  a.carriage_ = static_cast<size_t>(a.n_);
  a.has_extra_ = c.extra_mass_kg > 0.0;
  a.extra_ = a.ring_;
  a.rigid_wrap_ = !(b.backlash_m > 0.0);
  const size_t nodes = a.ring_ + (a.has_extra_ ? 1 : 0);
  a.x_.assign(nodes, 0.0);
  a.v_.assign(nodes, 0.0);
  a.f_.assign(nodes, 0.0);
  a.m_.assign(nodes, 0.0);
  a.inv_m_.assign(nodes, 0.0);
  a.k_seg_.assign(a.ring_, 0.0);
  a.c_seg_.assign(a.ring_, 0.0);
  if (a.has_extra_) {
    const double w = kTwoPi * c.extra_freq_hz;
    a.extra_k_ = c.extra_mass_kg * w * w;
    a.extra_c_ = 2.0 * c.extra_damping_ratio * c.extra_mass_kg * w;
  }
  a.ln_ratio_half_ = 0.5 * std::log(b.stiffness_ratio);

  // The field at u = start; the rotor in static equilibrium against the torque law (Eq. 2) and the
  // detent torque (Newton from the field's own angle).
  a.set_field_target(p.start_m);
  a.phi_f_ = a.phi_target_;
  const double nr = st.rotor_teeth;
  double th = a.phi_f_ / nr;
  for (int it = 0; it < 20; ++it) {
    const double t = -st.holding_torque_nm * std::sin(nr * th - a.phi_f_) -
                     st.detent_torque_nm * std::sin(4.0 * nr * th + st.detent_phase_rad);
    const double dt =
        -st.holding_torque_nm * nr * std::cos(nr * th - a.phi_f_) -
        st.detent_torque_nm * 4.0 * nr * std::cos(4.0 * nr * th + st.detent_phase_rad);
    th -= t / dt;
  }
  a.theta_ = th;
  const double p0 = a.pulley_m(th);
  std::fill(a.x_.begin(), a.x_.end(), p0);
  a.update_geometry(p0);
  a.friction_.set_z_m(0.0);
  // Tooth contact damping from the belt-on-pulley node's own mass.
  a.tooth_c_ = 2.0 * b.tooth_damping_ratio * std::sqrt(b.tooth_stiffness_n_m * a.m_[0]);
  a.max_step_s_ = a.compute_max_step();
  a.encoder_ = Encoder(p.encoder, p0, a.max_step_s_);
  a.encoder_.push(0.0, p0);
  a.encoder_zero_m_ = a.encoder_.reading_of(p0);
  return a;
}

double Axis2::pulley_m(double theta) const {
  const StepperParams& st = params_.stepper;
  if (st.runout_m == 0.0) return st.pulley_radius_m * theta;
  return st.pulley_radius_m * theta + st.runout_m * std::sin(theta + st.runout_phase_rad);
}

double Axis2::pulley_gain_m(double theta) const {
  const StepperParams& st = params_.stepper;
  if (st.runout_m == 0.0) return st.pulley_radius_m;
  return st.pulley_radius_m + st.runout_m * std::cos(theta + st.runout_phase_rad);
}

void Axis2::set_field_target(double u_m) {
  const StepperParams& st = params_.stepper;
  u_cached_m_ = u_m;
  // Commanded electrical angle phi_c = n_r theta_c, theta_c = u / r (Eq. 11), plus the microstep
  // angle error's two harmonics.
  const double phi_c = st.rotor_teeth * u_m / st.pulley_radius_m;
  phi_target_ = phi_c + st.microstep_err4_rad * std::sin(4.0 * phi_c + st.microstep_phase4_rad) +
                st.microstep_err1_rad * std::sin(phi_c + st.microstep_phase1_rad);
}

void Axis2::update_geometry(double x_m) {
  const BeltParams& b = params_.belt;
  double l[3];
  span_lengths(b, x_m, l);
  const double nd = n_;
  const double wrap_kg = b.linear_density_kg_m * kPi * params_.stepper.pulley_radius_m;
  geometry_x_m_ = x_m;
  std::fill(m_.begin(), m_.end(), 0.0);
  for (int j = 0; j < 3; ++j) {
    const double seg_len = l[j] / nd;
    const double k = b.specific_stiffness_n / seg_len;  // k^ / length (Eq. 6), per segment
    const double m_seg = b.linear_density_kg_m * seg_len;
    const double c = 2.0 * b.segment_damping_ratio * std::sqrt(k * m_seg);
    k_span_[j] = b.specific_stiffness_n / l[j];
    c_span_[j] = b.span_damping_s * k_span_[j];
    for (int s = 0; s < n_; ++s) {
      const size_t seg = static_cast<size_t>(j * n_ + s);
      k_seg_[seg] = k;
      c_seg_[seg] = c;
      // Each segment's mass shared by its two nodes.
      m_[seg] += 0.5 * m_seg;
      m_[(seg + 1) % ring_] += 0.5 * m_seg;
    }
  }
  m_[0] += wrap_kg;
  m_[carriage_] += params_.carriage.mass_kg;
  m_[2 * static_cast<size_t>(n_)] += b.idler_mass_kg;
  if (has_extra_) m_[extra_] = params_.carriage.extra_mass_kg;
  for (size_t i = 0; i < m_.size(); ++i) inv_m_[i] = 1.0 / m_[i];
}

double Axis2::compute_max_step() const {
  // The stiffest geometry: both variable spans at their shortest.
  const BeltParams& b = params_.belt;
  const StepperParams& st = params_.stepper;
  const double nd = n_;
  const double ratio = std::max(b.stiffness_ratio, 1.0 / b.stiffness_ratio);
  const double k_dir = std::sqrt(ratio);
  const double l_short = b.min_span_m;
  const double l_long = b.pulley_gap_m + b.travel_m + b.end_gap_m;
  const double k_seg = k_dir * b.specific_stiffness_n * nd / l_short;
  const double m_seg = b.linear_density_kg_m * l_short / nd;
  const double c_seg = 2.0 * b.segment_damping_ratio * std::sqrt(k_seg * m_seg);
  const double k_span = b.specific_stiffness_n / l_short;
  const double c_span = b.span_damping_s * k_span;
  const double c_long = b.span_damping_s * b.specific_stiffness_n / l_long;
  const double wrap_kg = b.linear_density_kg_m * kPi * st.pulley_radius_m;
  double rate = 0.0;
  auto consider = [&rate](double k, double c, double m) {
    rate = std::max(rate, std::sqrt(2.0 * k / m) + 2.0 * c / m);
  };
  // An interior belt node: two segments.
  consider(2.0 * k_seg, 2.0 * c_seg, m_seg);
  // The carriage: two segments, two span dampers, the bristles, the extra resonance.
  const LuGreParams& lg = friction_.params();
  const double w_extra = kTwoPi * params_.carriage.extra_freq_hz;
  const double k_extra = params_.carriage.extra_mass_kg * w_extra * w_extra;
  const double c_extra =
      2.0 * params_.carriage.extra_damping_ratio * params_.carriage.extra_mass_kg * w_extra;
  consider(2.0 * k_seg + lg.sigma0_n_m + k_extra,
           2.0 * c_seg + 2.0 * c_span + lg.sigma1_n_s_m + lg.sigma2_n_s_m + c_extra,
           params_.carriage.mass_kg + m_seg);
  if (params_.carriage.extra_mass_kg > 0.0)
    consider(k_extra, c_extra, params_.carriage.extra_mass_kg);
  // The idler.
  consider(2.0 * k_seg, 2.0 * c_seg + c_span + c_long, b.idler_mass_kg + m_seg);
  // The belt on the pulley and the rotor (in the pulley's linear coordinate, Eq. 14).
  const double r = st.pulley_radius_m + st.runout_m;
  const double nr = st.rotor_teeth;
  const double k_motor = (st.holding_torque_nm * nr + st.detent_torque_nm * 4.0 * nr) / (r * r);
  const double c_motor = (st.field_damping_nm_s_rad + st.bearing_damping_nm_s_rad) / (r * r);
  const double m_rotor = st.rotor_inertia_kg_m2 / (r * r);
  const double k_wrap = 2.0 * k_seg;
  const double c_wrap = 2.0 * c_seg + c_span + c_long;
  if (b.backlash_m > 0.0) {
    const double c_tooth = 2.0 * b.tooth_damping_ratio * std::sqrt(b.tooth_stiffness_n_m * wrap_kg);
    consider(k_wrap + b.tooth_stiffness_n_m, c_wrap + c_tooth, wrap_kg + m_seg);
    consider(k_motor + b.tooth_stiffness_n_m, c_motor + c_tooth, m_rotor);
  } else {
    consider(k_motor + k_wrap, c_motor + c_wrap, m_rotor + wrap_kg + m_seg);
  }
  return kStepFactor / rate;
}

void Axis2::advance(double u_m, double duration_s) {
  if (!(duration_s > 0.0)) return;
  const double n = std::ceil(duration_s / max_step_s_ - 1e-9);
  const int steps = std::max(1, static_cast<int>(n));
  const double dt = duration_s / steps;
  for (int i = 0; i < steps; ++i) step(u_m, dt);
}

void Axis2::step(double u_m, double dt_s) {
  const StepperParams& st = params_.stepper;
  const BeltParams& b = params_.belt;
  if (u_m != u_cached_m_) set_field_target(u_m);
  // The spans' lengths follow the carriage: refreshed every 0.1 mm of travel.
  if (std::fabs(x_[carriage_] - geometry_x_m_) > 1e-4) update_geometry(x_[carriage_]);
  if (dt_s != decay_dt_) {
    decay_dt_ = dt_s;
    decay_ = std::exp(-dt_s / st.field_tau_s);
  }
  // The field's lag: its rate now, then its exact advance over the step.
  const double phi_rate = (phi_target_ - phi_f_) / st.field_tau_s;

  // Forces on the belt nodes and the carriage.
  const size_t ring = ring_;
  const size_t c = carriage_;
  const double p = pulley_m(theta_);
  const double gain = pulley_gain_m(theta_);
  if (rigid_wrap_) {
    x_[0] = p;
    v_[0] = gain * omega_;
  }
  std::fill(f_.begin(), f_.end(), 0.0);
  // Direction-dependent stiffness: K(pulling +) / K(pulling -) = ratio, switched on the sign of
  // the pulley's lead over the carriage (thesis Eq. 6: sgn(-r theta - x_2)).
  double kdir = 1.0;
  if (ln_ratio_half_ != 0.0)
    kdir = std::exp(ln_ratio_half_ * std::tanh((p - x_[c]) / kDirectionSwitchM));
  for (size_t s = 0; s < ring; ++s) {
    const size_t a = s;
    const size_t e = s + 1 == ring ? 0 : s + 1;
    // Tension change of the segment (elongation x_e - x_a along the loop; the pretension cancels
    // around the loop). The upstream node is pulled forward, the downstream one back.
    const double t = kdir * k_seg_[s] * (x_[e] - x_[a]) + c_seg_[s] * (v_[e] - v_[a]);
    f_[a] += t;
    f_[e] -= t;
  }
  // Span dampers (the belt's material loss at the low modes), between each span's ends.
  const size_t idler = 2 * static_cast<size_t>(n_);
  const size_t ends[3][2] = {{0, c}, {c, idler}, {idler, 0}};
  for (int j = 0; j < 3; ++j) {
    const size_t a = ends[j][0];
    const size_t e = ends[j][1];
    const double t = c_span_[j] * (v_[e] - v_[a]);
    f_[a] += t;
    f_[e] -= t;
  }
  // LuGre friction on the carriage (thesis Eq. 4's F_f).
  // (z advances over the step with the speed at its start.)
  f_[c] -= friction_.step(v_[c], dt_s);
  // The extra resonance: a mass on a spring-damper on the carriage.
  if (has_extra_) {
    const double t = extra_k_ * (x_[extra_] - x_[c]) + extra_c_ * (v_[extra_] - v_[c]);
    f_[c] += t;
    f_[extra_] -= t;
  }

  // The rotor (thesis Eq. 1): torque law (Eq. 2) against the field, detent, damping, the belt.
  const double nr = st.rotor_teeth;
  double torque = -st.holding_torque_nm * std::sin(nr * theta_ - phi_f_) -
                  st.field_damping_nm_s_rad * (omega_ - phi_rate / nr) -
                  st.bearing_damping_nm_s_rad * omega_;
  if (st.detent_torque_nm != 0.0)
    torque -= st.detent_torque_nm * std::sin(4.0 * nr * theta_ + st.detent_phase_rad);
  double inertia = st.rotor_inertia_kg_m2;
  if (rigid_wrap_) {
    torque += gain * f_[0];  // the belt's pull on the pulley's pitch line
    inertia += m_[0] * gain * gain;
  } else {
    // Backlash: the teeth push the belt-on-pulley node only outside the dead band.
    const double gap = p - x_[0];
    const double half = 0.5 * b.backlash_m;
    double tooth = 0.0;
    if (gap > half) {
      tooth = b.tooth_stiffness_n_m * (gap - half) + tooth_c_ * (gain * omega_ - v_[0]);
    } else if (gap < -half) {
      tooth = b.tooth_stiffness_n_m * (gap + half) + tooth_c_ * (gain * omega_ - v_[0]);
    }
    f_[0] += tooth;
    torque -= gain * tooth;
  }

  // Semi-implicit Euler: velocities from the forces, then positions from the new velocities.
  omega_ += dt_s * torque / inertia;
  theta_ += dt_s * omega_;
  const size_t first = rigid_wrap_ ? 1 : 0;
  for (size_t i = first; i < x_.size(); ++i) {
    v_[i] += dt_s * f_[i] * inv_m_[i];
    x_[i] += dt_s * v_[i];
  }
  if (rigid_wrap_) {
    x_[0] = pulley_m(theta_);
    v_[0] = pulley_gain_m(theta_) * omega_;
  }
  phi_f_ = phi_target_ + (phi_f_ - phi_target_) * decay_;
  t_s_ += dt_s;
  encoder_.push(t_s_, x_[c]);
}

double Axis2::kinetic_energy_j() const {
  double e = 0.5 * params_.stepper.rotor_inertia_kg_m2 * omega_ * omega_;
  for (size_t i = 0; i < x_.size(); ++i) e += 0.5 * m_[i] * v_[i] * v_[i];
  return e;
}

double Axis2::measured_m() const {
  return params_.start_m + encoder_.raw_m(t_s_) - encoder_zero_m_;
}

double Axis2::measured_quantised_m() const {
  const double rel = encoder_.raw_m(t_s_) - encoder_zero_m_;
  const double res = params_.encoder.resolution_m;
  const double q = res > 0.0 ? std::round(rel / res) * res : rel;
  return params_.start_m + q;
}

}  // namespace feedloop::plant2
