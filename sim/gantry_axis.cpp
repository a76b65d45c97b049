// Time-domain integration of the gantry axis (see gantry_axis.hpp for the equations).
#include "sim/gantry_axis.hpp"

#include <algorithm>  // clamp, max
#include <cmath>      // sin, sqrt, abs, llround, ceil

namespace feedloop::sim {

namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr double kTimeEps_s = 1e-12;
// Dahl bristle deflection at full sliding friction: small against the positions of interest.
constexpr double kBristle_m = 20e-6;
constexpr double kInvBristle_per_m = 1.0 / kBristle_m;

size_t history_capacity(const GantryAxisParams& p) {
  const double delay_s = p.encoder.sampling_delay_s +
                         (p.effects.time_delay.enabled ? p.effects.time_delay.delay_ms * 1e-3 : 0.0);
  // Samples two apart are at least a substep apart (History::push): 2 d / h + 8 span d.
  return static_cast<size_t>(std::ceil(delay_s * p.substep_hz * 2.0)) + 8;
}

// Belt: Eq. 6's active length never falls below this fraction of the span (the model's clamp).
constexpr double kMinActiveSpan = 0.05;
// The sine law's stages: sin(phase0 + d) by angle addition from the substep's sin/cos of phase0,
// with Taylor series of sin d and cos d (exact to rounding below this |d|: the first omitted terms
// are d^13 / 13! and d^12 / 12!, < 2e-16 here). A stage moves the phase by h times the rotor's
// speed relative to the field: ~0.1 rad at a slip at 150 mm/s and 62.5 us.
constexpr double kMaxSeriesRad = 0.25;

// (Products with the reciprocals, not quotients: a compiler may not turn x / 6.0 into a product
// without -ffast-math, and the ten divisions were a quarter of the simulator's time.)
inline double sin_near(double phase, double phase0, double s0, double c0) {
  const double d = phase - phase0;
  if (!(std::abs(d) <= kMaxSeriesRad)) return std::sin(phase);
  const double d2 = d * d;
  const double sin_d =
      d *
      (1.0 - d2 * (1.0 / 6.0) *
                 (1.0 - d2 * (1.0 / 20.0) *
                            (1.0 - d2 * (1.0 / 42.0) *
                                       (1.0 - d2 * (1.0 / 72.0) * (1.0 - d2 * (1.0 / 110.0))))));
  const double cos_d =
      1.0 - d2 * 0.5 *
                (1.0 - d2 * (1.0 / 12.0) *
                           (1.0 - d2 * (1.0 / 30.0) *
                                      (1.0 - d2 * (1.0 / 56.0) * (1.0 - d2 * (1.0 / 90.0)))));
  return s0 * cos_d + c0 * sin_d;
}

// Dahl's bristle after the carriage moved dx_m from where the bristle was z0_m (the law in
// displacement, gantry_axis.hpp), exact for a displacement of one sign: a substep is far shorter
// than the time a carriage takes to reverse. The bristle's sliding rate |v2| / z_max (15 kHz at
// 0.3 m/s) therefore sets no substep, as it did when z was integrated in time.
inline double bristle_at(double dx_m, double z0_m) {
  if (dx_m == 0.0) return z0_m;
  const double s_m = dx_m > 0.0 ? kBristle_m : -kBristle_m;
  return s_m + (z0_m - s_m) * std::exp(-std::abs(dx_m) * kInvBristle_per_m);
}
}  // namespace

Result<GantryAxis> GantryAxis::create(const GantryAxisParams& p) {
  if (Status s = validate(p); !s) return Error{"gantry axis: " + s.error().message, s.error().where};
  if (p.substep_hz > 0.0) return GantryAxis(p);
  GantryAxisParams q = p;
  q.substep_hz = substep_hz_for(fastest_mode_rad_s(p));
  if (q.substep_hz > 1e6) return Error{"gantry axis: fastest mode above 1 MHz: set substep_hz", {}};
  return GantryAxis(q);
}

double GantryAxis::fastest_mode_rad_s(const GantryAxisParams& p) {
  GantryAxisParams q = p;
  q.substep_hz = 40000.0;  // any valid rate: only the model is used
  // In the dead band the belt carries nothing; outside it, its full stiffness.
  q.effects.backlash.enabled = false;
  double w = sim::fastest_mode_rad_s(GantryAxis(q).linearize().a);
  q.belt_stiffness_n_m /= kMinActiveSpan;  // K2 = k_hat / (0.05 L) = 20 k2 at x2 = 0
  w = std::max(w, sim::fastest_mode_rad_s(GantryAxis(q).linearize().a));
  if (std::isfinite(p.hard_stop_min_mm) || std::isfinite(p.hard_stop_max_mm) || p.coupled_stops)
    w = std::max(w, 2.0 * std::sqrt(p.hard_stop_n_m / p.carriage_mass_kg));  // the contact's mode
  return w;
}

GantryAxis::GantryAxis(const GantryAxisParams& p)
    : p_(p), encoder_(p.encoder, p.seed), history_(history_capacity(p), 1.0 / p.substep_hz) {
  h_s_ = 1.0 / p.substep_hz;
  stop_min_m_ = p.hard_stop_min_mm * 1e-3;
  stop_max_m_ = p.hard_stop_max_mm * 1e-3;
  stop_c_ = std::sqrt(p.hard_stop_n_m * p.carriage_mass_kg);  // 2 zeta sqrt(k m), zeta 0.5
  const double r_m = p.pulley_radius_mm * 1e-3;
  const double scale = p.effects.scale_error.enabled ? p.effects.scale_error.scale : 1.0;
  mm_per_step_nominal_ = 2.0 * kPi * p.pulley_radius_mm / (p.full_steps_per_rev * p.microsteps);
  m_per_step_true_ = mm_per_step_nominal_ * 1e-3 * scale;
  // One electrical period = 4 full steps = 2 pi r / n_r with n_r = full_steps_per_rev / 4.
  lambda_m_ = 2.0 * kPi * r_m * 4.0 / p.full_steps_per_rev * scale;
  f_hold_n_ = p.motor_stiffness_n_m * lambda_m_ / (2.0 * kPi);  // k1 = F_hold 2 pi / lambda (Eq. 8)
  tau_s_ = p.motor_damping_n_s_m / p.motor_stiffness_n_m;
  k_hat_ = p.belt_stiffness_n_m * p.belt_span_mm * 1e-3;
  read_delay_s_ = p.encoder.sampling_delay_s +
                  (p.effects.time_delay.enabled ? p.effects.time_delay.delay_ms * 1e-3 : 0.0);
  phase_per_m_ = 2.0 * kPi / lambda_m_;
  inv_tau_per_s_ = 1.0 / tau_s_;
  inv_corner_s_m_ =
      p.pullout_corner_speed_mm_s > 0.0 ? 1.0 / (p.pullout_corner_speed_mm_s * 1e-3) : 0.0;
  span_m_ = p.belt_span_mm * 1e-3;
  x0_m_ = p.belt_x0_mm * 1e-3;
  min_active_m_ = kMinActiveSpan * span_m_;
  inv_efficiency_ = 1.0 / p.efficiency;
  inv_m1_ = 1.0 / p.rotor_mass_kg;
  inv_m2_ = 1.0 / p.carriage_mass_kg;
  if (p.effects.periodic_position.enabled) {
    runout_m_ = p.effects.periodic_position.amplitude_um * 1e-6;
    runout_per_m_ = 2.0 * kPi / (p.effects.periodic_position.period_mm * 1e-3);
  }
  if (p.effects.backlash.enabled) backlash_half_m_ = 0.5 * p.effects.backlash.width_um * 1e-6;
  if (p.effects.coulomb_friction.enabled)
    friction_n_per_m_ = p.effects.coulomb_friction.force_n / kBristle_m;
  if (p.effects.extra_resonance.enabled) {
    const auto& er = p.effects.extra_resonance;
    const double w = 2.0 * kPi * er.freq_hz;
    extra_k_ = er.mass_kg * w * w;
    extra_c_ = 2.0 * er.damping * er.mass_kg * w;
    inv_m3_ = 1.0 / er.mass_kg;
  }
  u0_m_ = p.initial_pos_mm * 1e-3;
  const double x0_m = p.initial_pos_mm * 1e-3;
  x_ << x0_m, x0_m, 0.0, x0_m, 0.0, x0_m, 0.0, 0.0;
  xc_ = x_;
  history_.clear(0.0, x0_m);
}

void GantryAxis::add_coupled_stop(const GantryAxis& other, double own_coef, double other_coef,
                                  double min_mm, double max_mm) {
  if (num_coupled_ >= static_cast<int>(coupled_.size())) return;
  coupled_[static_cast<size_t>(num_coupled_++)] = {&other, own_coef, other_coef, min_mm * 1e-3,
                                                   max_mm * 1e-3};
}

double GantryAxis::commanded_mm() const {
  return p_.initial_pos_mm + static_cast<double>(steps_) * mm_per_step_nominal_;
}

GantryAxis::State GantryAxis::derivative(const State& x, double u_m) const {
  return derivative_(x, u_m, std::sin(phase_per_m_ * (x[kField] - x[kRotor])), nullptr);
}

GantryAxis::State GantryAxis::derivative_(const State& x, double u_m, double sin_phase,
                                          const SubstepStart* from) const {
  const double uf = x[kField], y1 = x[kRotor], v1 = x[kRotorVel];
  const double y2 = x[kCarriage], v2 = x[kCarriageVel], x3 = x[kExtra], v3 = x[kExtraVel];

  // Driver field: tau du_f/dt = u - u_f.
  const double duf = (u_m - uf) * inv_tau_per_s_;

  // Motor (Eq. 2-3 with the microstep equilibrium u_f; damping relative to the field, Eq. 9).
  double f_motor = 0.0;
  if (enabled_) {
    // Every electromagnetic force scales with the phase current, which falls with speed.
    const double vr = v1 * inv_corner_s_m_;
    const double current_frac = inv_corner_s_m_ > 0.0 ? 1.0 / std::sqrt(1.0 + vr * vr) : 1.0;
    f_motor = current_frac * (f_hold_n_ * sin_phase + p_.motor_damping_n_s_m * (duf - v1));
  }

  // Belt (Eq. 5-6), with pulley runout and backlash when enabled.
  double belt_rotor_m = y1;
  if (runout_m_ != 0.0) {
    const double phase = runout_per_m_ * y1;
    belt_rotor_m +=
        runout_m_ *
        (from != nullptr ? sin_near(phase, from->phase, from->sin, from->cos) : std::sin(phase));
  }
  double stretch_m = belt_rotor_m - y2;
  if (backlash_half_m_ > 0.0) {
    const double half_m = backlash_half_m_;
    stretch_m = stretch_m > half_m ? stretch_m - half_m : (stretch_m < -half_m ? stretch_m + half_m : 0.0);
  }
  const double sgn = stretch_m > 0.0 ? 1.0 : (stretch_m < 0.0 ? -1.0 : 0.0);
  const double active_m = std::max(span_m_ - (x0_m_ + y2) * sgn, min_active_m_);
  const double f_belt = k_hat_ / active_m * stretch_m;  // on the carriage; -f_belt / e on the rotor (Eq. 7)

  // Rails (Eq. 10) and Coulomb friction.
  double f_rail = -p_.bearing_damping_n_s_m * v2;
  double dz = 0.0;
  if (friction_n_per_m_ > 0.0) {
    double z = x[kBristle];
    if (from != nullptr)
      z = bristle_at(y2 - from->carriage_m, from->bristle_m);  // integrate_ sets z after the step
    else
      dz = v2 - std::abs(v2) * z * kInvBristle_per_m;
    f_rail -= friction_n_per_m_ * z;
  }

  // The hard stops: a stiff contact while the carriage is past one.
  if (y2 < stop_min_m_) f_rail += p_.hard_stop_n_m * (stop_min_m_ - y2) - stop_c_ * v2;
  if (y2 > stop_max_m_) f_rail -= p_.hard_stop_n_m * (y2 - stop_max_m_) + stop_c_ * v2;

  // Stops on a coordinate shared with another belt (CoreXY), its force times own_coef here.
  for (int i = 0; i < num_coupled_; ++i) {
    const CoupledStop& cs = coupled_[static_cast<size_t>(i)];
    const State& o = cs.other->xc_;
    const double c = cs.own * y2 + cs.other_coef * o[kCarriage];
    const double vc = cs.own * v2 + cs.other_coef * o[kCarriageVel];
    double f = 0.0;
    if (c < cs.min_m) f = p_.hard_stop_n_m * (cs.min_m - c) - stop_c_ * vc;
    if (c > cs.max_m) f = -p_.hard_stop_n_m * (c - cs.max_m) - stop_c_ * vc;
    f_rail += cs.own * f;
  }

  // Extra mass on its mount (extra_resonance): a spring-damper to the carriage.
  const double f_mount = inv_m3_ > 0.0 ? extra_k_ * (x3 - y2) + extra_c_ * (v3 - v2) : 0.0;
  State d;
  d << duf, v1, (f_motor - f_belt * inv_efficiency_) * inv_m1_, v2,
      (f_belt + f_rail + f_mount) * inv_m2_, v3, -f_mount * inv_m3_, dz;
  return d;
}

void GantryAxis::integrate_(State& x, double h) const {
  const double u = (static_cast<double>(steps_) + step_fraction_) * m_per_step_true_ + u0_m_;
  const double phase0 = phase_per_m_ * (x[kField] - x[kRotor]);
  const double s0 = std::sin(phase0), c0 = std::cos(phase0);
  SubstepStart start;  // what the stages take from the substep's start (gantry_axis.hpp)
  if (runout_m_ != 0.0) {
    start.phase = runout_per_m_ * x[kRotor];
    start.sin = std::sin(start.phase);
    start.cos = std::cos(start.phase);
  }
  start.carriage_m = x[kCarriage];
  start.bristle_m = x[kBristle];
  auto stage = [&](const State& xs) {
    return derivative_(xs, u, sin_near(phase_per_m_ * (xs[kField] - xs[kRotor]), phase0, s0, c0),
                       &start);
  };
  const State k1 = derivative_(x, u, s0, &start);
  const State k2 = stage(x + (0.5 * h) * k1);
  const State k3 = stage(x + (0.5 * h) * k2);
  const State k4 = stage(x + h * k3);
  x += (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
  if (friction_n_per_m_ > 0.0)
    x[kBristle] = bristle_at(x[kCarriage] - start.carriage_m, start.bristle_m);
}

void GantryAxis::after_substep_() {
  history_.push(tc_s_, xc_[kCarriage]);
  const auto n = static_cast<int64_t>(std::llround((xc_[kField] - xc_[kRotor]) / lambda_m_));
  if (n != slip_periods_) {
    slip_events_ += n > slip_periods_ ? n - slip_periods_ : slip_periods_ - n;
    slip_periods_ = n;
  }
}

// Whole substeps from the last input event (or the last whole substep after it) up to t_s.
void GantryAxis::commit_substeps_(double t_s) {
  while (t_s - tc_s_ >= h_s_ - kTimeEps_s) {
    integrate_(xc_, h_s_);
    tc_s_ += h_s_;
    after_substep_();
  }
}

// A look at time t_s: the whole substeps are committed, the rest is integrated on a copy (the
// view). So where the integration's substeps fall depends only on the input events (the steps,
// enable), never on when someone looked: a run's trajectory does not depend on when the host
// read the plant or the MCU sampled its encoder (issue 13's run-to-run comparison on the wall
// clock; docs/decisions.md, "One motion, one clock frame").
void GantryAxis::advance_to(double t_s) {
  if (t_s - t_s_ <= kTimeEps_s) return;  // the view never goes back
  commit_substeps_(t_s);
  x_ = xc_;
  if (t_s - tc_s_ > kTimeEps_s) integrate_(x_, t_s - tc_s_);
  t_s_ = t_s;
}

// An input changes at t_s: the committed state goes exactly there (a partial substep), and the
// substep grid restarts from it.
void GantryAxis::commit_to_(double t_s) {
  if (t_s - tc_s_ <= kTimeEps_s) return;  // late (before the committed time): counted by the caller
  commit_substeps_(t_s);
  if (t_s - tc_s_ > kTimeEps_s) {
    integrate_(xc_, t_s - tc_s_);
    tc_s_ = t_s;
    after_substep_();
  }
  x_ = xc_;
  t_s_ = std::max(t_s_, tc_s_);
}

void GantryAxis::step(double t_s, int direction) {
  if (t_s < tc_s_) ++late_events_;
  commit_to_(t_s);
  steps_ += direction >= 0 ? 1 : -1;
  if (t_s_ > tc_s_) advance_to_view_();
}

void GantryAxis::set_step_fraction(double t_s, float fraction) {
  const double f = std::clamp(static_cast<double>(fraction), -1.0, 1.0);
  if (f == step_fraction_) return;
  if (t_s < tc_s_) ++late_events_;
  commit_to_(t_s);
  step_fraction_ = f;
  if (t_s_ > tc_s_) advance_to_view_();
}

void GantryAxis::set_enabled(double t_s, bool enabled) {
  if (t_s < tc_s_) ++late_events_;
  commit_to_(t_s);
  enabled_ = enabled;
  if (t_s_ > tc_s_) advance_to_view_();
}

// After an input event that lies before the view's time: the view is recomputed with it.
void GantryAxis::advance_to_view_() {
  const double t = t_s_;
  t_s_ = tc_s_;
  advance_to(t);
}

int64_t GantryAxis::read_encoder_counts(double t_s) {
  if (t_s < t_s_) ++late_events_;
  advance_to(t_s);
  const double pos_m = read_delay_s_ > 0.0 ? history_.value_at(t_s_ - read_delay_s_) : x_[kCarriage];
  return encoder_.counts((pos_m - p_.initial_pos_mm * 1e-3) * 1e3);
}

bool GantryAxis::read_encoder_index(double t_s) {
  const double period_mm = p_.encoder.index_period_mm;
  if (!(period_mm > 0.0)) return false;
  advance_to(t_s);
  const double pos_m =
      read_delay_s_ > 0.0 ? history_.value_at(t_s_ - read_delay_s_) : x_[kCarriage];
  // The marks at odd multiples of half a period in machine coordinates (encoder.hpp).
  const double from_mark_mm = pos_m * 1e3 - 0.5 * period_mm;
  const double in_period_mm = from_mark_mm - std::floor(from_mark_mm / period_mm) * period_mm;
  return in_period_mm < encoder_.mm_per_count();
}

LinearModel GantryAxis::linearize() const {
  const double u0 = (static_cast<double>(steps_) + step_fraction_) * m_per_step_true_ + u0_m_;
  Dynamics f = [this](const Eigen::VectorXd& x, const Eigen::VectorXd& u) -> Eigen::VectorXd {
    return derivative(State(x), u[0]);
  };
  Eigen::VectorXd dx(8);
  dx << 1e-9, 1e-9, 1e-6, 1e-9, 1e-6, 1e-9, 1e-6, 1e-9;
  Eigen::MatrixXd c = Eigen::MatrixXd::Zero(1, 8);
  c(0, kCarriage) = 1.0;
  Eigen::VectorXd u(1);
  u << u0;
  LinearModel m = linearize_dynamics(f, Eigen::VectorXd(x_), u, dx, 1e-9, c);
  return m;  // SI in and out: a position-to-position FRF has the same value in mm
}

}  // namespace feedloop::sim
