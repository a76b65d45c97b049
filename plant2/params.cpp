// Validation of the second simulator's parameters (see params.hpp).
#include "plant2/params.hpp"

#include <cmath>
#include <string>

namespace feedloop::plant2 {

namespace {

bool positive(double v) {
  return std::isfinite(v) && v > 0.0;
}
bool non_negative(double v) {
  return std::isfinite(v) && v >= 0.0;
}

Status fail(const std::string& what) {
  return Error{"plant2: " + what, {}};
}

}  // namespace

Status validate(const Axis2Params& p) {
  const StepperParams& s = p.stepper;
  if (!positive(s.holding_torque_nm)) return fail("holding torque must be > 0");
  if (s.rotor_teeth < 1) return fail("rotor teeth must be >= 1");
  if (s.microsteps < 1) return fail("microsteps must be >= 1");
  if (!positive(s.rotor_inertia_kg_m2)) return fail("rotor inertia must be > 0");
  if (!positive(s.pulley_radius_m)) return fail("pulley radius must be > 0");
  if (!positive(s.field_tau_s)) return fail("field time constant must be > 0");
  if (!non_negative(s.field_damping_nm_s_rad) || !non_negative(s.bearing_damping_nm_s_rad))
    return fail("rotor damping must be >= 0");
  if (!non_negative(s.detent_torque_nm)) return fail("detent torque must be >= 0");
  if (!non_negative(s.runout_m) || s.runout_m >= 0.1 * s.pulley_radius_m)
    return fail("pulley runout must be in [0, r / 10)");
  const BeltParams& b = p.belt;
  if (!positive(b.specific_stiffness_n)) return fail("belt stiffness must be > 0");
  if (!positive(b.linear_density_kg_m)) return fail("belt density must be > 0");
  if (b.segments_per_span < 4) return fail("segments per span must be >= 4");
  if (!positive(b.pulley_gap_m) || !positive(b.travel_m) || !positive(b.end_gap_m))
    return fail("belt geometry must be > 0");
  if (!positive(b.min_span_m) || b.min_span_m > b.pulley_gap_m || b.min_span_m > b.end_gap_m)
    return fail("min span must be > 0 and <= both end gaps");
  if (!positive(b.idler_mass_kg)) return fail("idler mass must be > 0");
  if (!non_negative(b.span_damping_s) || !non_negative(b.segment_damping_ratio))
    return fail("belt damping must be >= 0");
  if (!non_negative(b.backlash_m)) return fail("backlash must be >= 0");
  if (!positive(b.tooth_stiffness_n_m) || !non_negative(b.tooth_damping_ratio))
    return fail("tooth contact must have stiffness > 0");
  if (!positive(b.stiffness_ratio)) return fail("stiffness ratio must be > 0");
  const CarriageParams& c = p.carriage;
  if (!positive(c.mass_kg)) return fail("carriage mass must be > 0");
  if (!non_negative(c.coulomb_n) || !non_negative(c.static_n) || !positive(c.stribeck_m_s) ||
      !positive(c.bristle_stiffness_n_m) || !non_negative(c.bristle_damping_n_s_m) ||
      !non_negative(c.viscous_n_s_m))
    return fail("friction parameters out of range");
  if (!non_negative(c.extra_mass_kg) || !positive(c.extra_freq_hz) ||
      !non_negative(c.extra_damping_ratio))
    return fail("extra resonance parameters out of range");
  const EncoderParams& e = p.encoder;
  if (!non_negative(e.resolution_m) || !positive(e.interp_period_m) ||
      !non_negative(e.interp_amplitude_m) || !positive(e.scale))
    return fail("encoder parameters out of range");
  if (!positive(e.max_delay_s) || !non_negative(e.delay_s) || e.delay_s > e.max_delay_s)
    return fail("encoder delay must be in [0, max_delay_s]");
  if (!std::isfinite(p.start_m) || p.start_m < -b.pulley_gap_m + b.min_span_m ||
      p.start_m > b.travel_m + b.end_gap_m - b.min_span_m)
    return fail("start position outside the belt's geometry");
  return Status::Ok();
}

}  // namespace feedloop::plant2
