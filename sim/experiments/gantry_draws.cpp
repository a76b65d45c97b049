// Random thesis axes with one undeclared effect: see gantry_draws.hpp for the ranges.
#include "sim/experiments/gantry_draws.hpp"

#include "core/rng.hpp"

namespace feedloop::sim {

namespace {
double uniform_in(Rng& rng, double lo, double hi) {
  return lo + (hi - lo) * rng.uniform();
}
}  // namespace

DrawnGantryAxis draw_gantry_axis(uint64_t seed, std::optional<ident::Effect> kind) {
  Rng rng(0x5eed0000ULL ^ (seed * 0x9E3779B97F4A7C15ULL));
  DrawnGantryAxis d;
  d.axis = rng.uniform() < 0.5 ? 'x' : 'y';
  GantryAxisParams& p = d.params;
  p = d.axis == 'x' ? thesis_x_axis() : thesis_y_axis();
  p.motor_stiffness_n_m *= uniform_in(rng, 0.8, 1.25);
  p.belt_stiffness_n_m *= uniform_in(rng, 0.8, 1.25);
  p.motor_damping_n_s_m *= uniform_in(rng, 0.8, 1.25);
  p.bearing_damping_n_s_m *= uniform_in(rng, 0.8, 1.25);
  p.rotor_mass_kg *= uniform_in(rng, 0.9, 1.1);
  p.carriage_mass_kg *= uniform_in(rng, 0.9, 1.1);
  p.belt_span_mm =
      1e6;        // the linear model's belt everywhere (docs/simulator.md) unless drawn below
  p.seed = seed;  // encoder noise
  d.effect = kind;
  if (!kind) return d;
  GantryEffects& fx = p.effects;
  using ident::Effect;
  switch (*kind) {
    case Effect::kPeriodicPosition:
      fx.periodic_position = {true, uniform_in(rng, 20.0, 40.0), uniform_in(rng, 8.0, 30.0)};
      d.key_param = "amplitude_um";
      d.key_value = fx.periodic_position.amplitude_um;
      break;
    case Effect::kCoulombFriction:
      fx.coulomb_friction = {true, uniform_in(rng, 0.8, 4.0)};
      d.key_param = "force_n";
      d.key_value = fx.coulomb_friction.force_n;
      break;
    case Effect::kBacklash:
      fx.backlash = {true, uniform_in(rng, 15.0, 60.0)};
      d.key_param = "width_um";
      d.key_value = fx.backlash.width_um;
      break;
    case Effect::kDirectionStiffness: {
      // K2 = k_hat / (L - (x0 + x2) sgn(x1 - x2)) (gantry_params.hpp): pulling + over pulling -
      // is (L + x0) / (L - x0) at x2 = 0, so x0 = L (r - 1) / (r + 1).
      const double ratio = uniform_in(rng, 1.4, 2.2);
      p.belt_span_mm = 350.0;
      p.belt_x0_mm = p.belt_span_mm * (ratio - 1.0) / (ratio + 1.0);
      d.key_param = "ratio";
      d.key_value = ratio;
      d.needs_fixed_position = true;
      break;
    }
    case Effect::kExtraResonance:
      fx.extra_resonance = {true, uniform_in(rng, 25.0, 80.0), uniform_in(rng, 0.03, 0.1),
                            uniform_in(rng, 0.1, 0.25)};
      d.key_param = "freq_hz";
      d.key_value = fx.extra_resonance.freq_hz;
      break;
    case Effect::kTimeDelay:
      fx.time_delay = {true, uniform_in(rng, 2.0, 10.0)};
      d.key_param = "delay_ms";
      d.key_value = fx.time_delay.delay_ms;
      break;
    case Effect::kScaleError: {
      const double size = uniform_in(rng, 0.002, 0.01);
      fx.scale_error = {true, 1.0 + (rng.uniform() < 0.5 ? -size : size)};
      d.key_param = "scale";
      d.key_value = fx.scale_error.scale;
      break;
    }
  }
  return d;
}

}  // namespace feedloop::sim
