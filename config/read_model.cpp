// Config section `model`: the thesis gantry model per axis (Appendix D) and the delta LPV model
// (delta paper Table I physical parameters).
#include "config/enum_names.hpp"
#include "config/sections.hpp"
#include "model/lead_lag.hpp"

namespace feedloop::config::detail {
namespace {

void read_stepper(MapReader& g, StepperConfig& st, Diagnostics& diag) {
  MapReader s = g.sub("stepper");
  s.number("holding_torque_nm", st.holding_torque_nm, Range::positive());
  const bool r = s.number("rated_current_a", st.rated_current_a, Range::positive());
  const bool d = s.number("drive_current_a", st.drive_current_a, Range::positive());
  if ((r || d) && st.drive_current_a > st.rated_current_a * 1.5)
    diag.add(s.key_mark("drive_current_a"),
             s.path() + ": drive_current_a (" + format_number(st.drive_current_a) +
                 " A) is more than 1.5 x rated_current_a (" + format_number(st.rated_current_a) +
                 " A)");
  s.integer_as("rotor_teeth", st.rotor_teeth, 1, 1000);
  s.number("rotor_inertia_kg_m2", st.rotor_inertia_kg_m2, Range::positive());
  s.number("pulley_radius_mm", st.pulley_radius_mm, Range::positive());
  // 0: a uniform belt, k2 at every position and in both directions (no Eq. 6 schedule).
  s.number("belt_unit_stiffness_n", st.belt_unit_stiffness_n, Range::non_negative());
  s.number("pulley_distance_mm", st.pulley_distance_mm, Range::positive());
  s.number("belt_efficiency", st.belt_efficiency, Range::open_closed(0.0, 1.0));
  s.finish();
}

}  // namespace

void read_gantry_axis(MapReader& g, GantryModelConfig& m, Need six, Diagnostics& diag) {
  // Plausible for any printer's axis, and wide around what identification fits (k1 2e4-2e7, k2
  // 2e3-2e6, c1 1-2e5, c2 0.1-2e3; the thesis: m1 0.13 kg, m2 0.45-1.07 kg): a value outside is
  // a typo or a unit slip (N/mm for N/m), not a machine, and the feedforward would be designed on
  // it (k2: 1e300 was accepted).
  g.number("m1_kg", m.m1_kg, Range::closed(1e-4, 100.0), six);
  g.number("m2_kg", m.m2_kg, Range::closed(1e-3, 1000.0), six);
  g.number("k1_n_per_m", m.k1_n_per_m, Range::closed(100.0, 1e10), six);
  g.number("k2_n_per_m", m.k2_n_per_m, Range::closed(100.0, 1e10), six);
  g.number("c1_ns_per_m", m.c1_ns_per_m, Range::closed(0.0, 1e7), six);
  g.number("c2_ns_per_m", m.c2_ns_per_m, Range::closed(0.0, 1e7), six);
  g.number("coulomb_friction_n", m.coulomb_friction_n, Range::closed(0.0, 1000.0));
  // 0.5 um - 1 mm: the identification fits 1-300 um.
  g.number("friction_bristle_mm", m.friction_bristle_mm, Range::closed(0.0005, 1.0));
  g.number("backlash_mm", m.backlash_mm, Range::closed(0.0, 1.0));
  // Identification fits 0.4-2.5; a belt ten times stiffer one way than the other is a typo.
  g.number("belt_direction_ratio", m.belt_direction_ratio, Range::closed(0.1, 10.0));
  // A compliance that doubles or halves within 100 mm is not a belt (calibrate fits -10..10).
  g.number("belt_compliance_slope_per_m", m.belt_compliance_slope_per_m,
           Range::closed(-50.0, 50.0));
  g.number("belt_stiffness_reference_mm", m.belt_stiffness_reference_mm, Range::closed(-1e5, 1e5));
  // Identification looks for periods of 2 mm to half the travel and amplitudes of microns.
  g.number("runout_period_mm", m.runout_period_mm, Range::closed(0.0, 2000.0));
  g.number("runout_sin_um", m.runout_sin_um, Range::closed(-1000.0, 1000.0));
  g.number("runout_cos_um", m.runout_cos_um, Range::closed(-1000.0, 1000.0));
  g.number("runout_reference_mm", m.runout_reference_mm, Range::closed(-1e5, 1e5));
  // Identification reports scales within 2 % of 1 (a pulley 2 % off its nominal is not a print);
  // beyond 10 % the steps_per_mm is wrong, not the model.
  g.number("travel_scale", m.travel_scale, Range::closed(0.9, 1.1));
  // Identification fits modes of 10-300 Hz, damped 0.001-0.19, of a fraction of the carriage.
  g.number("extra_resonance_hz", m.extra_resonance_hz, Range::closed(0.0, 1000.0));
  g.number("extra_resonance_damping", m.extra_resonance_damping, Range::closed(0.0, 1.0));
  g.number("extra_resonance_mass_kg", m.extra_resonance_mass_kg, Range::closed(0.0, 100.0));
  if (m.extra_resonance_mass_kg > 0.0 && !(m.extra_resonance_hz > 0.0))
    diag.add(g.key_mark("extra_resonance_hz"),
             "extra_resonance_hz must be > 0 when extra_resonance_mass_kg is (" +
                 format_number(m.extra_resonance_mass_kg) + " kg): the mode's natural frequency");
  // Up to 50 ms: the identification's delays are a few ms; a device loop compares its encoder
  // with a target sent this much later (engine/mcu_bridge.cpp).
  g.number("encoder_delay_ms", m.encoder_delay_ms, Range::closed(0.0, 50.0));
  // A current loop's lag is tens of microseconds, a slow driver's a few ms.
  g.number("field_lag_ms", m.field_lag_ms, Range::closed(0.0, 20.0));
  // With a field lag c1 damps the load angle, and c1 / k1 is the inverse's pole: without it the
  // feedforward's lead-lag would ring at half the servo rate (control/feedforward/gantry_lpv.cpp).
  if (m.field_lag_ms > 0.0 && !(m.c1_ns_per_m / m.k1_n_per_m >= model::kMinFieldDampingLagS))
    diag.add(g.key_mark("field_lag_ms"),
             "field_lag_ms needs the motor's damping: c1_ns_per_m / k1_n_per_m is " +
                 format_number(m.c1_ns_per_m / m.k1_n_per_m * 1e3) +
                 " ms, under 0.01 ms (c1 damps the load angle when the field lags)");
  read_stepper(g, m.stepper, diag);
}

bool gantry_axis_known(const MachineConfig& cfg, const std::string& name, const YAML::Mark& where,
                       Diagnostics& diag) {
  if (cfg.kinematics == Kinematics::delta) {
    diag.add(where,
             "model.gantry is for cartesian and corexy machines; a delta uses "
             "model.delta_lpv");
    return false;
  }
  if (cfg.axis(name) == nullptr) {
    std::vector<std::string> names;
    for (const AxisConfig& a : cfg.axes) names.push_back(a.name);
    std::string msg = "model.gantry: '" + name + "' is not an axis in axes";
    if (const std::string s = closest_match(name, names); !s.empty())
      msg += " (did you mean '" + s + "'?)";
    diag.add(where, msg);
    return false;
  }
  return true;
}

namespace {

void read_gantry(MapReader& model, MachineConfig& cfg, Diagnostics& diag) {
  MapReader gantry = model.sub("gantry");
  for (const std::string& name : gantry.keys()) {
    const YAML::Mark where = gantry.key_mark(name);
    MapReader g(gantry.get(name), gantry.key_path(name), diag, where);
    if (!gantry_axis_known(cfg, name, where, diag)) continue;
    GantryModelConfig m;
    m.axis = name;
    // Eq. 13: the six parameters differ per axis, so none defaults silently.
    read_gantry_axis(g, m, Need::required, diag);
    g.finish();
    cfg.model.gantry.push_back(m);
  }
  gantry.finish();
}

void read_delta_lpv(MapReader& model, MachineConfig& cfg, Diagnostics& diag) {
  if (!model.has("delta_lpv")) {
    model.sub("delta_lpv");  // known key
    return;
  }
  MapReader d = model.sub("delta_lpv");
  if (cfg.kinematics != Kinematics::delta) {
    diag.add(model.key_mark("delta_lpv"), "model.delta_lpv is only valid with kinematics: delta");
    return;
  }
  DeltaLpvConfig p;
  d.number("m_c_kg", p.m_c_kg, Range::positive());
  d.number("m_f_kg", p.m_f_kg, Range::non_negative());
  d.number("c_ns_per_m", p.c_ns_per_m, Range::non_negative());
  d.number("b_ns_per_m", p.b_ns_per_m, Range::non_negative());
  d.number("k_n_per_m", p.k_n_per_m, Range::positive());
  // G_qd,e = (d1 s + d0) / (s^2 + d2 s + d0): d0 > 0 and d2 > 0 for a stable mode; d1 may be
  // negative (the paper's -212.1 is a right-half-plane zero).
  d.number("d0_per_s2", p.d0_per_s2, Range::positive());
  d.number("d1_per_s", p.d1_per_s, Range::any());
  d.number("d2_per_s", p.d2_per_s, Range::positive());
  d.number("m1_kg", p.m1_kg, Range::positive());
  d.number("m2_kg", p.m2_kg, Range::positive());
  d.number("b_x_ns_per_m", p.b_x_ns_per_m, Range::non_negative());
  d.number("b_y_ns_per_m", p.b_y_ns_per_m, Range::non_negative());
  d.number("b_z_ns_per_m", p.b_z_ns_per_m, Range::non_negative());
  d.number("k_x_n_per_m", p.k_x_n_per_m, Range::positive());
  d.number("k_y_n_per_m", p.k_y_n_per_m, Range::positive());
  d.number("k_z_n_per_m", p.k_z_n_per_m, Range::positive());
  d.number("delta_x_mm", p.delta_x_mm, Range::any());
  d.number("delta_y_mm", p.delta_y_mm, Range::any());
  d.number("delta_z_mm", p.delta_z_mm, Range::any());
  d.number("d_e_mm", p.d_e_mm, Range::positive());
  d.number("gravity_m_s2", p.gravity_m_s2, Range::closed(0.0, 100.0));
  d.choice("force_transform", p.force_transform, force_transform_names());
  d.finish();
  cfg.model.delta_lpv = p;
}

}  // namespace

// Table I of output-maneuvering-cartesian: the plant of drive: dc_servo.
void read_cartesian_dc(MapReader& model, MachineConfig& cfg, Diagnostics& diag) {
  if (!model.has("cartesian_dc")) {
    model.sub("cartesian_dc");  // known key
    return;
  }
  MapReader d = model.sub("cartesian_dc");
  if (cfg.drive != Drive::dc_servo)  // reported once; the keys are still checked below
    diag.add(model.key_mark("cartesian_dc"), "model.cartesian_dc is the plant of drive: dc_servo (this machine "
                                             "has drive: stepper)");
  CartesianDcConfig& p = cfg.model.cartesian_dc;
  d.number("m_n_kg", p.m_n_kg, Range::positive());
  d.number("m_x_kg", p.m_x_kg, Range::non_negative());
  d.number("m_ps_kg", p.m_ps_kg, Range::positive());
  d.number("j_m_kg_m2", p.j_m_kg_m2, Range::non_negative());
  d.number("b_nm_s", p.b_nm_s, Range::non_negative());
  d.number("r_a_ohm", p.r_a_ohm, Range::positive());
  d.number("k_m_nm_per_a", p.k_m_nm_per_a, Range::positive());
  d.number("pulley_radius_mm", p.pulley_radius_mm, Range::positive());
  d.finish();
}

void read_model(MapReader& root, MachineConfig& cfg, Diagnostics& diag) {
  MapReader model = root.sub("model");
  read_gantry(model, cfg, diag);
  read_delta_lpv(model, cfg, diag);
  read_cartesian_dc(model, cfg, diag);
  model.finish();
}

}  // namespace feedloop::config::detail
