// Presets and validation for GantryAxisParams (see gantry_params.hpp and docs/simulator.md).
#include "sim/gantry_params.hpp"

#include <cmath>   // isfinite
#include <string>

namespace feedloop::sim {

GantryAxisParams thesis_x_axis() {
  GantryAxisParams p;  // the defaults are the X axis
  return p;
}

GantryAxisParams thesis_y_axis() {
  GantryAxisParams p;
  // Table 3 masses; k1, k2, c1, c2 solve Eq. 16 = Eq. 18 (G_Y) exactly (Table 4: 392 kN/m,
  // 19.7 kN/m, 411 N s/m, 71.5 N s/m).
  p.carriage_mass_kg = 1.07;
  p.motor_stiffness_n_m = 390747.0;
  p.belt_stiffness_n_m = 19814.0;
  p.motor_damping_n_s_m = 409.95;
  p.bearing_damping_n_s_m = 71.7733;
  // The Y driver runs at a quarter of the rated current (Table 3): with this roll-off the axis
  // keeps 150 mm/s at 1000-3000 mm/s^2 but loses steps at 6000 mm/s^2 and at a 300 mm/s
  // speed change, as in Sect. 5.3-5.4.
  p.pullout_corner_speed_mm_s = 55.0;
  return p;
}

namespace {
Status positive(double v, const char* name) {
  if (!(v > 0.0) || !std::isfinite(v)) return Error{std::string(name) + " must be > 0", {}};
  return Status::Ok();
}
}  // namespace

Status validate(const GantryAxisParams& p) {
  const std::pair<double, const char*> pos[] = {{p.motor_stiffness_n_m, "motor_stiffness_n_m"},
                                                {p.rotor_mass_kg, "rotor_mass_kg"},
                                                {p.motor_damping_n_s_m, "motor_damping_n_s_m"},
                                                {p.pulley_radius_mm, "pulley_radius_mm"},
                                                {p.belt_stiffness_n_m, "belt_stiffness_n_m"},
                                                {p.belt_span_mm, "belt_span_mm"},
                                                {p.efficiency, "efficiency"},
                                                {p.carriage_mass_kg, "carriage_mass_kg"}};
  for (const auto& [v, name] : pos)
    if (Status s = positive(v, name); !s) return s;
  if (p.efficiency > 1.0) return Error{"efficiency must be in (0, 1]", {}};
  if (!(p.bearing_damping_n_s_m >= 0.0)) return Error{"bearing_damping_n_s_m must be >= 0", {}};
  if (!(p.pullout_corner_speed_mm_s >= 0.0)) return Error{"pullout_corner_speed_mm_s must be >= 0", {}};
  if (p.full_steps_per_rev < 4 || p.full_steps_per_rev % 4 != 0)
    return Error{"full_steps_per_rev must be a positive multiple of 4 (n_r = full steps / 4)", {}};
  if (p.microsteps < 1 || p.microsteps > 256) return Error{"microsteps must be in [1, 256]", {}};
  if (std::abs(p.initial_pos_mm + p.belt_x0_mm) >= 0.9 * p.belt_span_mm)
    return Error{"initial position too close to a pulley: |x0 + x2| must stay below 0.9 L", {}};
  if (p.substep_hz != 0.0 && !(p.substep_hz >= 1000.0 && p.substep_hz <= 1e6))
    return Error{"substep_hz must be 0 (from the fastest mode) or in [1 kHz, 1 MHz]", {}};
  if (Status s = validate(p.encoder); !s) return s;
  const GantryEffects& e = p.effects;
  if (e.coulomb_friction.enabled && !(e.coulomb_friction.force_n >= 0.0))
    return Error{"coulomb_friction.force_n must be >= 0", {}};
  if (e.backlash.enabled && !(e.backlash.width_um >= 0.0)) return Error{"backlash.width_um must be >= 0", {}};
  if (e.periodic_position.enabled) {
    if (Status s = positive(e.periodic_position.period_mm, "periodic_position.period_mm"); !s) return s;
    if (!std::isfinite(e.periodic_position.amplitude_um)) return Error{"periodic_position.amplitude_um must be finite", {}};
  }
  if (e.extra_resonance.enabled) {
    if (Status s = positive(e.extra_resonance.freq_hz, "extra_resonance.freq_hz"); !s) return s;
    if (Status s = positive(e.extra_resonance.mass_kg, "extra_resonance.mass_kg"); !s) return s;
    if (!(e.extra_resonance.damping >= 0.0)) return Error{"extra_resonance.damping must be >= 0", {}};
    if (p.substep_hz > 0.0 && e.extra_resonance.freq_hz > 0.2 * p.substep_hz)
      return Error{"extra_resonance.freq_hz must be below substep_hz / 5", {}};
  }
  if (e.time_delay.enabled && !(e.time_delay.delay_ms >= 0.0 && e.time_delay.delay_ms <= 1000.0))
    return Error{"time_delay.delay_ms must be in [0, 1000]", {}};
  if (e.scale_error.enabled && !(e.scale_error.scale > 0.5 && e.scale_error.scale < 2.0))
    return Error{"scale_error.scale must be in (0.5, 2)", {}};
  return Status::Ok();
}

}  // namespace feedloop::sim
