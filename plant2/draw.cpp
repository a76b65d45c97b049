// Random machines and effects of the second simulator (see draw.hpp, docs/plant2.md).
#include "plant2/draw.hpp"

#include <cmath>
#include <cstdio>
#include <limits>

#include "core/rng.hpp"

namespace feedloop::plant2 {

namespace {

constexpr double kTwoPi = 6.283185307179586;

struct Uniform {
  Rng rng;
  double operator()(double lo, double hi) { return lo + (hi - lo) * rng.uniform(); }
  double phase() { return kTwoPi * rng.uniform(); }
  bool coin() { return rng.uniform() < 0.5; }
};

// The baseline machine: every parameter around the thesis's X and Y axes.
Axis2Params draw_baseline(Uniform& u) {
  Axis2Params p;
  StepperParams& s = p.stepper;
  // Holding torque: the 17HD0013's 0.285 N m derated to 1/4-1/2 current (Table 3) up to a
  // stronger NEMA 17 at a similar fraction: k_1 = T n_r / r^2 = 171-429 kN/m, covering Table 3's
  // 122-244 and Table 4's 355-392 kN/m.
  s.holding_torque_nm = u(0.10, 0.25);
  s.rotor_inertia_kg_m2 = u(3.2e-6, 4.5e-6);  // 38 g cm^2 (Table 2) +- 15 %
  s.pulley_radius_m = 5.40e-3;                // the config's mm per step is calibrated: r is exact
  s.field_tau_s = u(30e-6, 150e-6);
  const double r2 = s.pulley_radius_m * s.pulley_radius_m;
  s.field_damping_nm_s_rad = u(150.0, 600.0) * r2;  // c_1 (Eq. 14) 150-600 N s/m (Y: 411)
  // Small baseline microstep errors and detent: at most ~1.5 um of carriage ripple (a good
  // driver and motor); the periodic_position effect draws big ones.
  const double to_elec = s.rotor_teeth / s.pulley_radius_m;  // carriage m -> electrical rad
  s.microstep_err4_rad = u(0.0, 1.0e-6) * to_elec;
  s.microstep_phase4_rad = u.phase();
  s.microstep_err1_rad = u(0.0, 1.0e-6) * to_elec;
  s.microstep_phase1_rad = u.phase();
  s.detent_torque_nm = u(0.005, 0.015) * s.holding_torque_nm;
  s.detent_phase_rad = u.phase();
  BeltParams& b = p.belt;
  // E A of a 6 mm GT2 belt: ~4-12 kN; gives k_2 = 26-110 kN/m mid-travel (Table 4: 19.7-110).
  b.specific_stiffness_n = u(4000.0, 12000.0);
  b.linear_density_kg_m = u(6.5e-3, 8.5e-3);
  b.pulley_gap_m = u(0.030, 0.060);
  b.travel_m = u(0.200, 0.300);
  b.end_gap_m = u(0.030, 0.060);
  b.idler_mass_kg = u(2e-3, 5e-3);
  b.span_damping_s = u(5e-5, 2e-4);
  CarriageParams& c = p.carriage;
  c.mass_kg = u(0.35, 1.20);  // extruder 0.45 kg (X) to X carriage 1.07 kg (Y), Table 2
  c.coulomb_n = u(0.05, 0.25);
  c.static_n = c.coulomb_n * u(1.1, 1.5);
  c.stribeck_m_s = u(1e-3, 5e-3);
  c.bristle_stiffness_n_m = c.static_n / u(2e-6, 8e-6);  // pre-sliding 2-8 um at breakaway
  c.viscous_n_s_m = u(10.0, 40.0);
  EncoderParams& e = p.encoder;
  e.resolution_m = 0.488e-6;  // AS5311: 2 mm / 4096 (thesis Sect. 4.2)
  e.interp_period_m = u.coin() ? 20e-6 : 40e-6;
  e.interp_amplitude_m = u(0.1e-6, 0.6e-6);
  e.interp_phase_rad = u.phase();
  p.start_m = 0.100;
  return p;
}

void add_effect(Draw& d, Uniform& u) {
  Axis2Params& p = d.params;
  StepperParams& s = p.stepper;
  TrueEffect e;
  e.name = effect_name(d.kind);
  const double r = s.pulley_radius_m;
  switch (d.kind) {
    case EffectKind::none:
      return;
    case EffectKind::periodic_position: {
      const int source = static_cast<int>(std::floor(3.0 * u.rng.uniform()));
      const double to_elec = s.rotor_teeth / r;
      double period_m = 0.0, amp_m = 0.0;
      if (source == 0) {
        amp_m = u(10e-6, 40e-6);
        s.runout_m = amp_m;
        s.runout_phase_rad = u.phase();
        period_m = kTwoPi * r;
        e.source = "pulley runout";
      } else if (source == 1) {
        amp_m = u(4e-6, 12e-6);
        s.microstep_err4_rad = amp_m * to_elec;
        s.microstep_phase4_rad = u.phase();
        period_m = kTwoPi * r / (4.0 * s.rotor_teeth);
        e.source = "microstep angle error, once per full step";
      } else {
        amp_m = u(4e-6, 12e-6);
        s.microstep_err1_rad = amp_m * to_elec;
        s.microstep_phase1_rad = u.phase();
        period_m = kTwoPi * r / s.rotor_teeth;
        e.source = "microstep angle error, once per electrical cycle";
      }
      e.params = {{"period_mm", period_m * 1e3}, {"amplitude_um", amp_m * 1e6}};
      break;
    }
    case EffectKind::coulomb_friction: {
      CarriageParams& c = p.carriage;
      c.coulomb_n = u(1.5, 5.0);
      c.static_n = c.coulomb_n * u(1.1, 1.4);
      c.bristle_stiffness_n_m = c.static_n / u(2e-6, 8e-6);
      e.params = {{"force_n", c.coulomb_n}, {"static_n", c.static_n}};
      e.source = "LuGre friction of the carriage's bearings";
      break;
    }
    case EffectKind::backlash: {
      p.belt.backlash_m = u(20e-6, 120e-6);
      e.params = {{"width_um", p.belt.backlash_m * 1e6}};
      e.source = "dead band between the pulley's teeth and the belt";
      break;
    }
    case EffectKind::direction_dependent_stiffness: {
      double ratio = u(1.3, 2.0);
      if (u.coin()) ratio = 1.0 / ratio;
      p.belt.stiffness_ratio = ratio;
      e.params = {{"ratio", ratio}};
      e.source = "belt stiffness K(pulling +) / K(pulling -)";
      break;
    }
    case EffectKind::extra_resonance: {
      CarriageParams& c = p.carriage;
      c.extra_freq_hz = u(40.0, 150.0);
      c.extra_damping_ratio = u(0.02, 0.08);
      c.extra_mass_kg = c.mass_kg * u(0.15, 0.35);
      e.params = {{"freq_hz", c.extra_freq_hz},
                  {"damping", c.extra_damping_ratio},
                  {"mass_kg", c.extra_mass_kg}};
      e.source = "a mass on a spring-damper on the carriage";
      break;
    }
    case EffectKind::time_delay: {
      p.encoder.delay_s = u(0.3e-3, 2.0e-3);
      e.params = {{"delay_ms", p.encoder.delay_s * 1e3}};
      e.source = "transport delay of the encoder's reading";
      break;
    }
    case EffectKind::scale_error: {
      const double dev = u(0.002, 0.008);
      p.encoder.scale = u.coin() ? 1.0 + dev : 1.0 - dev;
      e.params = {{"scale", p.encoder.scale}};
      e.source = "encoder scale (measured travel / true travel)";
      break;
    }
  }
  d.effects.push_back(std::move(e));
}

}  // namespace

const char* effect_name(EffectKind kind) {
  switch (kind) {
    case EffectKind::none:
      return "none";
    case EffectKind::periodic_position:
      return "periodic_position";
    case EffectKind::coulomb_friction:
      return "coulomb_friction";
    case EffectKind::backlash:
      return "backlash";
    case EffectKind::direction_dependent_stiffness:
      return "direction_dependent_stiffness";
    case EffectKind::extra_resonance:
      return "extra_resonance";
    case EffectKind::time_delay:
      return "time_delay";
    case EffectKind::scale_error:
      return "scale_error";
  }
  return "none";
}

std::optional<EffectKind> effect_kind_from_name(std::string_view name) {
  for (EffectKind k : kAllEffectKinds)
    if (name == effect_name(k)) return k;
  return std::nullopt;
}

double TrueEffect::param(std::string_view n) const {
  for (const auto& [key, value] : params)
    if (key == n) return value;
  return std::numeric_limits<double>::quiet_NaN();
}

Draw draw_axis(uint64_t seed, EffectKind kind) {
  Draw d;
  d.seed = seed;
  d.kind = kind;
  Uniform base{Rng(seed)};
  d.params = draw_baseline(base);
  // The effect's own stream: the baseline does not change with the kind.
  Uniform eff{
      Rng(seed * 0x9E3779B97F4A7C15ULL + 0x632BE59BD9B4E019ULL + static_cast<uint64_t>(kind))};
  add_effect(d, eff);
  return d;
}

bool in_stated_range(const TrueEffect& e) {
  auto within = [](double v, double lo, double hi) { return v >= lo && v <= hi; };
  const double v = e.key_value();
  if (e.name == "periodic_position") {
    const double amp = e.param("amplitude_um");
    const double period = e.param("period_mm");
    if (std::fabs(period - 33.929) < 0.01) return within(amp, 10.0, 40.0);
    if (std::fabs(period - 0.16965) < 1e-4 || std::fabs(period - 0.67858) < 1e-4)
      return within(amp, 4.0, 12.0);
    return false;
  }
  if (e.name == "coulomb_friction") return within(v, 1.5, 5.0);
  if (e.name == "backlash") return within(v, 20.0, 120.0);
  if (e.name == "direction_dependent_stiffness")
    return within(v, 1.3, 2.0) || within(1.0 / v, 1.3, 2.0);
  if (e.name == "extra_resonance") return within(v, 40.0, 150.0);
  if (e.name == "time_delay") return within(v, 0.3, 2.0);
  if (e.name == "scale_error") return within(std::fabs(v - 1.0), 0.002, 0.008);
  return false;
}

std::string describe(const Draw& d) {
  if (d.effects.empty()) return "none";
  std::string out;
  for (const TrueEffect& e : d.effects) {
    out += e.name;
    for (const auto& [k, v] : e.params) {
      char buf[64];
      std::snprintf(buf, sizeof buf, " %s=%.6g", k.c_str(), v);
      out += buf;
    }
    out += " (" + e.source + ")";
  }
  return out;
}

}  // namespace feedloop::plant2
