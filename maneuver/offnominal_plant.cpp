// The off-nominal DC-motor printer plant (offnominal_plant.hpp).
#include "maneuver/offnominal_plant.hpp"

#include <algorithm>  // std::clamp, std::min
#include <cmath>
#include <random>
#include <sstream>

namespace feedloop::maneuver {

namespace {
constexpr double kPi = 3.14159265358979323846;
}  // namespace

std::string OffNominalParams::describe() const {
  std::ostringstream o;
  o.precision(3);
  o << "mass x" << mass_scale.x() << "/" << mass_scale.y() << "/" << mass_scale.z() << ", J_m x"
    << motor_inertia_scale << ", B x" << viscous_scale << ", K_m x" << torque_constant_scale
    << ", R_a x" << resistance_scale << ", back-EMF " << (back_emf ? "on" : "off") << ", L/R "
    << electrical_time_constant_s * 1e3 << " ms, limits " << voltage_limit_v << " V / "
    << force_limit_n << " N, belt " << belt_stiffness_n_m * 1e-3 << " N/mm (zeta "
    << belt_damping_ratio << "), friction F_c " << coulomb_n << " N F_s " << static_n << " N v_s "
    << stribeck_velocity_m_s * 1e3 << " mm/s, encoder " << encoder_resolution_m * 1e6
    << " um on the " << (encoder_on_carriage ? "carriage" : "motor") << ", delay "
    << measurement_delay_s * 1e6 << " us, velocity "
    << (differenced_velocity ? "differenced" : "exact");
  if (differenced_velocity && velocity_filter_hz > 0.0)
    o << " (low-pass " << velocity_filter_hz << " Hz)";
  return o.str();
}

OffNominalParams draw_offnominal(uint64_t seed) {
  std::mt19937_64 rng(seed);
  auto u = [&](double lo, double hi) {
    return std::uniform_real_distribution<double>(lo, hi)(rng);
  };
  OffNominalParams p;
  p.mass_scale = Vec3(u(0.8, 1.5), u(0.8, 1.5), u(0.8, 1.5));  // heavier tool heads and beds
  p.motor_inertia_scale = u(0.8, 1.3);
  p.viscous_scale = u(0.5, 3.0);
  p.torque_constant_scale = u(0.9, 1.1);  // catalogue tolerance
  p.resistance_scale = u(1.0, 1.4);       // copper from 20 to ~120 degrees C
  p.back_emf = true;
  p.electrical_time_constant_s = u(0.2e-3, 1.0e-3);
  p.voltage_limit_v = 24.0;                // rating, not drawn
  p.force_limit_n = 40.0;                  // rating, not drawn
  p.belt_stiffness_n_m = u(5.0e4, 2.0e5);  // GT2 6 mm over 0.3-1 m
  p.belt_damping_ratio = u(0.02, 0.1);
  p.coulomb_n = u(0.5, 3.0);
  p.static_n = p.coulomb_n * u(1.1, 1.6);
  p.stribeck_velocity_m_s = u(0.5e-3, 5e-3);
  p.encoder_on_carriage = false;
  p.encoder_resolution_m = 2.0 * kPi * p.nominal.r_m / 65536.0;  // 2^16 counts per turn: 0.96 um
  p.measurement_delay_s = u(10e-6, 60e-6);  // the servo MCU reads its own encoder
  p.differenced_velocity = true;
  p.velocity_filter_hz = 2000.0;
  return p;
}

OffNominalPlant::OffNominalPlant(const OffNominalParams& p) : p_(p) {
  const CartesianDcParams& n = p.nominal;
  const double r = n.r_m;
  const double jr2 = n.j_m_kg_m2 * p.motor_inertia_scale / (r * r);
  const double carriage[3] = {n.m_n_kg * p.mass_scale.x(), n.m_ps_kg * p.mass_scale.y(),
                              (n.m_n_kg + n.m_x_kg) * p.mass_scale.z()};
  for (size_t a = 0; a < 3; ++a) {
    AxisConst& c = c_[a];
    c.m_carriage = carriage[a];
    c.m_motor = p.belt_stiffness_n_m > 0.0 ? jr2 : jr2 + carriage[a];
    c.b = n.b_nm_s_rad * p.viscous_scale / (r * r);
    c.km_r = n.k_m_nm_a * p.torque_constant_scale / r;
    c.r_ohm = n.r_a_ohm * p.resistance_scale;
    c.l_h = p.electrical_time_constant_s * c.r_ohm;
    c.i_max = p.force_limit_n > 0.0 ? p.force_limit_n / c.km_r : 0.0;
    c.k_belt = p.belt_stiffness_n_m;
    // c_b = 2 zeta sqrt(k m_red), m_red the two masses in series.
    const double m_red = jr2 * carriage[a] / (jr2 + carriage[a]);
    c.c_belt = c.k_belt > 0.0 ? 2.0 * p.belt_damping_ratio * std::sqrt(c.k_belt * m_red) : 0.0;
    c.gravity_n = a == 2 ? carriage[a] * n.g_m_s2 : 0.0;
  }
  const double h = p.integration_step_s;
  delay_steps_ =
      std::min(kHistory - 1, static_cast<size_t>(std::lround(p.measurement_delay_s / h)));
  reset(Vec3::Zero());
}

double OffNominalPlant::friction_n(double v) const {
  if (p_.coulomb_n <= 0.0 && p_.static_n <= 0.0) return 0.0;
  const double fs = std::max(p_.static_n, p_.coulomb_n);
  const double x = v / p_.stribeck_velocity_m_s;
  const double level = p_.coulomb_n + (fs - p_.coulomb_n) * std::exp(-x * x);
  return level * std::tanh(v / p_.smoothing_velocity_m_s);
}

OffNominalPlant::Axis OffNominalPlant::derivative(const Axis& s, const AxisConst& c,
                                                  double v) const {
  Axis d;
  const double emf_v = p_.back_emf ? c.km_r * s.vm : 0.0;  // K_m omega = (K_m / r) q_m'
  double i = s.i;
  if (c.l_h > 0.0) {
    d.i = (v - c.r_ohm * s.i - emf_v) / c.l_h;
    if (c.i_max > 0.0 && std::abs(s.i) >= c.i_max && d.i * s.i > 0.0)
      d.i = 0.0;  // the driver's limit
  } else {
    i = (v - emf_v) / c.r_ohm;
    if (c.i_max > 0.0) i = std::clamp(i, -c.i_max, c.i_max);
  }
  const double motor_n = c.km_r * i;
  if (c.k_belt > 0.0) {
    const double belt_n = c.k_belt * (s.qm - s.qc) + c.c_belt * (s.vm - s.vc);
    d.qm = s.vm;
    d.vm = (motor_n - c.b * s.vm - belt_n) / c.m_motor;
    d.qc = s.vc;
    d.vc = (belt_n - friction_n(s.vc) - c.gravity_n) / c.m_carriage;
  } else {
    d.qm = s.vm;
    d.vm = (motor_n - c.b * s.vm - friction_n(s.vm) - c.gravity_n) / c.m_motor;
    d.qc = d.qm;
    d.vc = d.vm;
  }
  return d;
}

void OffNominalPlant::clamp_current(Axis& s, const AxisConst& c) const {
  if (c.l_h > 0.0 && c.i_max > 0.0) s.i = std::clamp(s.i, -c.i_max, c.i_max);
}

double OffNominalPlant::sensed(size_t a) const {
  return p_.encoder_on_carriage ? s_[a].qc : s_[a].qm;
}

void OffNominalPlant::reset(const Vec3& at_m) {
  for (size_t a = 0; a < 3; ++a) {
    const AxisConst& c = c_[a];
    Axis& s = s_[a];
    s = Axis{};
    s.qc = at_m[a];
    // At rest in equilibrium: the belt carries the weight, the current holds it.
    s.qm = at_m[a] + (c.k_belt > 0.0 ? c.gravity_n / c.k_belt : 0.0);
    s.i = c.gravity_n / c.km_r;
    if (p_.belt_stiffness_n_m <= 0.0) s.qm = s.qc;
  }
  for (auto& h : history_)
    for (size_t a = 0; a < 3; ++a) h[a] = sensed(a);
  for (auto& h : history_v_) h.fill(0.0);
  head_ = 0;
  auto quantize = [&](double x) {
    return p_.encoder_resolution_m > 0.0
               ? std::floor(x / p_.encoder_resolution_m) * p_.encoder_resolution_m
               : x;
  };
  for (size_t a = 0; a < 3; ++a) {
    measured_.x1_m[a] = quantize(sensed(a));
    measured_.x2_m_s[a] = 0.0;
  }
  last_counts_m_ = measured_.x1_m;
  limited_ = false;
}

void OffNominalPlant::step(double h, const Vec3& v) {
  for (size_t a = 0; a < 3; ++a) {
    const AxisConst& c = c_[a];
    const Axis& s = s_[a];
    auto add = [](const Axis& x, const Axis& d, double k) {
      return Axis{x.qm + k * d.qm, x.vm + k * d.vm, x.i + k * d.i, x.qc + k * d.qc,
                  x.vc + k * d.vc};
    };
    const Axis k1 = derivative(s, c, v[a]);
    Axis x2 = add(s, k1, 0.5 * h);
    clamp_current(x2, c);
    const Axis k2 = derivative(x2, c, v[a]);
    Axis x3 = add(s, k2, 0.5 * h);
    clamp_current(x3, c);
    const Axis k3 = derivative(x3, c, v[a]);
    Axis x4 = add(s, k3, h);
    clamp_current(x4, c);
    const Axis k4 = derivative(x4, c, v[a]);
    Axis next;
    next.qm = s.qm + h / 6.0 * (k1.qm + 2.0 * k2.qm + 2.0 * k3.qm + k4.qm);
    next.vm = s.vm + h / 6.0 * (k1.vm + 2.0 * k2.vm + 2.0 * k3.vm + k4.vm);
    next.i = s.i + h / 6.0 * (k1.i + 2.0 * k2.i + 2.0 * k3.i + k4.i);
    next.qc = s.qc + h / 6.0 * (k1.qc + 2.0 * k2.qc + 2.0 * k3.qc + k4.qc);
    next.vc = s.vc + h / 6.0 * (k1.vc + 2.0 * k2.vc + 2.0 * k3.vc + k4.vc);
    clamp_current(next, c);
    if (c.l_h > 0.0 && c.i_max > 0.0 && std::abs(next.i) >= c.i_max) limited_ = true;
    if (c.l_h <= 0.0 && c.i_max > 0.0 &&
        std::abs((v[a] - (p_.back_emf ? c.km_r * next.vm : 0.0)) / c.r_ohm) >= c.i_max)
      limited_ = true;
    s_[a] = next;
  }
  head_ = (head_ + 1) % kHistory;
  for (size_t a = 0; a < 3; ++a) {
    history_[head_][a] = sensed(a);
    history_v_[head_][a] = p_.encoder_on_carriage ? s_[a].vc : s_[a].vm;
  }
}

void OffNominalPlant::advance(const Vec3& w_v, double period_s) {
  limited_ = false;
  Vec3 v = w_v;
  if (p_.voltage_limit_v > 0.0)
    for (size_t a = 0; a < 3; ++a)
      if (std::abs(v[a]) > p_.voltage_limit_v) {
        v[a] = std::clamp(v[a], -p_.voltage_limit_v, p_.voltage_limit_v);
        limited_ = true;
      }
  const double hmax = p_.integration_step_s;
  const int n = std::max(1, static_cast<int>(std::ceil(period_s / hmax - 1e-9)));
  const double h = period_s / n;
  for (int i = 0; i < n; ++i) step(h, v);
  // The sample at the end of the period: the position sensed delay_steps_ substeps ago.
  const size_t at = (head_ + kHistory - delay_steps_) % kHistory;
  for (size_t a = 0; a < 3; ++a) {
    double x = history_[at][a];
    if (p_.encoder_resolution_m > 0.0)
      x = std::floor(x / p_.encoder_resolution_m) * p_.encoder_resolution_m;
    measured_.x1_m[a] = x;
    if (!p_.differenced_velocity) {
      measured_.x2_m_s[a] = history_v_[at][a];
    } else {
      const double raw = (x - last_counts_m_[a]) / period_s;
      const double alpha = p_.velocity_filter_hz > 0.0
                               ? 1.0 - std::exp(-2.0 * kPi * p_.velocity_filter_hz * period_s)
                               : 1.0;
      measured_.x2_m_s[a] += alpha * (raw - measured_.x2_m_s[a]);
    }
    last_counts_m_[a] = x;
  }
}

Vec3 OffNominalPlant::nozzle_m() const {
  return Vec3(s_[0].qc, s_[1].qc, s_[2].qc);
}

Vec3 OffNominalPlant::nozzle_velocity_m_s() const {
  return Vec3(s_[0].vc, s_[1].vc, s_[2].vc);
}

}  // namespace feedloop::maneuver
