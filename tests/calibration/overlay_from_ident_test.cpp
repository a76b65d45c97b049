// What the calibration overlay takes from a fit (calibration/overlay_from_ident.hpp).
#include "calibration/overlay_from_ident.hpp"

#include <gtest/gtest.h>

#include "config/config.hpp"
#include "control/feedforward/gantry_lpv.hpp"

#include <algorithm>  // std::find
#include <cmath>
#include <utility>  // std::make_pair

namespace feedloop::calibration {
namespace {

// Eq. 13's parameters of one axis (kg, N/m, N s/m).
config::GantryModelConfig eq13(double m1, double m2, double k1, double k2, double c1, double c2) {
  config::GantryModelConfig g;
  g.m1_kg = m1;
  g.m2_kg = m2;
  g.k1_n_per_m = k1;
  g.k2_n_per_m = k2;
  g.c1_ns_per_m = c1;
  g.c2_ns_per_m = c2;
  return g;
}

// The second simulator's seed 3 (Y): the fit put c1 at 2.3 N s/m with k1 2.6 MN/m on m1 0.13 kg,
// a rotor mode of 712 Hz at damping ratio 0.002; the floor raises c1 to zeta 0.05 and leaves the
// well-damped carriage alone.
TEST(DampingFloor, RaisesOnlyTheSpringWhoseModeIsBarelyDamped) {
  config::GantryModelConfig g = eq13(0.13, 0.45, 2618092.0, 59305.9, 2.30, 51.27);
  EXPECT_TRUE(apply_damping_floor(g, 0.05));
  EXPECT_NEAR(g.c1_ns_per_m, 2.0 * 0.05 * std::sqrt(2618092.0 * 0.13), 1e-9);
  EXPECT_NEAR(g.c1_ns_per_m, 58.34, 0.01);
  EXPECT_DOUBLE_EQ(g.c2_ns_per_m, 51.27);  // zeta 0.157 already
  // A model above the floor (the thesis's X axis, Table 4) is not touched.
  config::GantryModelConfig thesis = eq13(0.13, 0.45, 355e3, 110e3, 2100.0, 112.0);
  const config::GantryModelConfig copy = thesis;
  EXPECT_FALSE(apply_damping_floor(thesis, 0.05));
  EXPECT_DOUBLE_EQ(thesis.c1_ns_per_m, copy.c1_ns_per_m);
  EXPECT_DOUBLE_EQ(thesis.c2_ns_per_m, copy.c2_ns_per_m);
}

// The gains calibrate chose replace the overlay's (or go, with none), and the model, effects and
// source stay as they were.
TEST(OverlayWithGains, ReplacesOnlyTheGains) {
  const config::MachineConfig base = config::default_config();
  const std::string overlay =
      "calibration_version: 1\nsource: \"fit\"\nmodel:\n  gantry:\n    x: {k1_n_per_m: 298000}\n"
      "effects:\n  - {axis: x, name: backlash, params: {width_um: 40}, in_model: true}\n";
  auto with = overlay_with_gains(base, overlay, "cal.yaml", {{"x", 0.125, 5.0}, {"y", 0.125, 5.0}});
  ASSERT_TRUE(with.ok()) << with.error().to_string();
  auto a = config::apply_calibration_text(base, with.value(), "cal.yaml");
  ASSERT_TRUE(a.ok()) << a.error().to_string() << "\n" << with.value();
  EXPECT_EQ(a.value().config.control.gains_for("x").kp, 0.125);
  EXPECT_EQ(a.value().config.control.gains_for("y").ki_per_s, 5.0);
  EXPECT_EQ(a.value().config.model.gantry_for("x")->k1_n_per_m, 298000.0);
  ASSERT_EQ(a.value().effects.size(), 1u);
  EXPECT_EQ(a.value().effects[0].params.at("width_um"), 40.0);
  EXPECT_EQ(a.value().source, "fit");
  // None: the config's gains again.
  auto without = overlay_with_gains(base, with.value(), "cal.yaml", {});
  ASSERT_TRUE(without.ok());
  auto b = config::apply_calibration_text(base, without.value(), "cal.yaml");
  ASSERT_TRUE(b.ok());
  EXPECT_EQ(b.value().config.control, base.control);
  EXPECT_EQ(b.value().config.model, a.value().config.model);
  // A broken overlay is its error, not a silent empty one.
  EXPECT_FALSE(overlay_with_gains(base, "calibration_version: 9\n", "cal.yaml", {}).ok());
}

// Calibrate's trial of the carried sizes scales one size of one axis (here the friction force);
// the other axis, the other sizes, the effects as identified, the gains and the source stay as
// they were.
TEST(OverlayWithSizeScaled, ScalesOneSizeOfOneAxisAndNothingElse) {
  const config::MachineConfig base = config::default_config();
  constexpr double config::GantryModelConfig::*kFriction =
      &config::GantryModelConfig::coulomb_friction_n;
  const std::string overlay =
      "calibration_version: 1\nsource: \"fit\"\nmodel:\n  gantry:\n"
      "    x: {k1_n_per_m: 298000, coulomb_friction_n: 2.4, backlash_mm: 0.05}\n"
      "    y: {coulomb_friction_n: 5.1}\n"
      "effects:\n  - {axis: x, name: coulomb_friction, params: {force_n: 2.4}, in_model: true}\n"
      "control:\n  axes:\n    x: {kp: 0.25, ki_per_s: 10}\n";
  auto half = overlay_with_size_scaled(base, overlay, "cal.yaml", "x", kFriction, 0.5);
  ASSERT_TRUE(half.ok()) << half.error().to_string();
  auto a = config::apply_calibration_text(base, half.value(), "cal.yaml");
  ASSERT_TRUE(a.ok()) << a.error().to_string() << "\n" << half.value();
  EXPECT_DOUBLE_EQ(a.value().config.model.gantry_for("x")->coulomb_friction_n, 1.2);
  EXPECT_DOUBLE_EQ(a.value().config.model.gantry_for("y")->coulomb_friction_n, 5.1);
  EXPECT_EQ(a.value().config.model.gantry_for("x")->k1_n_per_m, 298000.0);
  EXPECT_EQ(a.value().config.model.gantry_for("x")->backlash_mm, 0.05);
  ASSERT_EQ(a.value().effects.size(), 1u);
  EXPECT_EQ(a.value().effects[0].params.at("force_n"), 2.4);  // as identified
  EXPECT_EQ(a.value().config.control.gains_for("x").kp, 0.25);
  EXPECT_EQ(a.value().source, "fit");
  // 0 takes the axis's friction out of the feedforward.
  auto none = overlay_with_size_scaled(base, overlay, "cal.yaml", "y", kFriction, 0.0);
  ASSERT_TRUE(none.ok());
  auto b = config::apply_calibration_text(base, none.value(), "cal.yaml");
  ASSERT_TRUE(b.ok());
  EXPECT_EQ(b.value().config.model.gantry_for("y")->coulomb_friction_n, 0.0);
  EXPECT_DOUBLE_EQ(b.value().config.model.gantry_for("x")->coulomb_friction_n, 2.4);
  // Another size: the dead band.
  auto wider = overlay_with_size_scaled(base, overlay, "cal.yaml", "x",
                                        &config::GantryModelConfig::backlash_mm, 1.5);
  ASSERT_TRUE(wider.ok());
  auto c = config::apply_calibration_text(base, wider.value(), "cal.yaml");
  ASSERT_TRUE(c.ok());
  EXPECT_DOUBLE_EQ(c.value().config.model.gantry_for("x")->backlash_mm, 0.075);
  EXPECT_DOUBLE_EQ(c.value().config.model.gantry_for("x")->coulomb_friction_n, 2.4);
  // A size scaled out of the config's range (a dead band over 1 mm): an error naming the key.
  const std::string wide = "calibration_version: 1\nmodel:\n  gantry:\n    x: {backlash_mm: 0.8}\n";
  auto over = overlay_with_size_scaled(base, wide, "cal.yaml", "x",
                                       &config::GantryModelConfig::backlash_mm, 1.5);
  ASSERT_FALSE(over.ok());
  EXPECT_NE(over.error().to_string().find("backlash_mm"), std::string::npos)
      << over.error().to_string();
  // An axis the overlay has no model of, and a broken overlay: errors.
  const std::string x_only =
      "calibration_version: 1\nmodel:\n  gantry:\n    x: {coulomb_friction_n: 1}\n";
  auto missing = overlay_with_size_scaled(base, x_only, "cal.yaml", "y", kFriction, 0.5);
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("no model of axis y"), std::string::npos);
  EXPECT_FALSE(
      overlay_with_size_scaled(base, "calibration_version: 9\n", "cal.yaml", "x", kFriction, 0.5)
          .ok());
}

// An identified time_delay flows into the model as the encoder's delay (the loops and e_t compare
// the reading with the reference of the instant it shows), and its effect says so.
TEST(OverlayFromIdent, TheTimeDelayBecomesTheEncodersDelay) {
  const config::MachineConfig base = config::default_config();
  ident::IdentResult r;
  r.axis = "x";
  r.augmented = ident::preset_axis_model("x");
  r.augmented.set(ident::Effect::kTimeDelay, true);
  r.augmented.delay_ms = 3.25;
  r.effects = {ident::Effect::kTimeDelay};
  auto yaml = merge_overlay(base, "", "", r, "fit");
  ASSERT_TRUE(yaml.ok()) << yaml.error().to_string();
  auto a = config::apply_calibration_text(base, yaml.value(), "cal.yaml");
  ASSERT_TRUE(a.ok()) << a.error().to_string() << "\n" << yaml.value();
  ASSERT_NE(a.value().config.model.gantry_for("x"), nullptr);
  EXPECT_DOUBLE_EQ(a.value().config.model.gantry_for("x")->encoder_delay_ms, 3.25);
  ASSERT_EQ(a.value().effects.size(), 1u);
  EXPECT_EQ(a.value().effects[0].name, "time_delay");
  EXPECT_TRUE(a.value().effects[0].in_model);
  // Without the effect: no delay.
  r.augmented.set(ident::Effect::kTimeDelay, false);
  r.effects.clear();
  auto none = config::apply_calibration_text(base, merge_overlay(base, "", "", r, "fit").value(),
                                             "cal.yaml");
  ASSERT_TRUE(none.ok());
  EXPECT_EQ(none.value().config.model.gantry_for("x")->encoder_delay_ms, 0.0);
  // Out of range in an overlay: located.
  auto bad = config::apply_calibration_text(
      base, "calibration_version: 1\nmodel:\n  gantry:\n    x: {encoder_delay_ms: 80}\n",
      "cal.yaml");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().to_string().find("encoder_delay_ms"), std::string::npos)
      << bad.error().to_string();
}

// A named scale error is the feedforward's travel_scale; a scale beyond the config's range (the
// fit found something else) and no scale_error leave 1.
TEST(OverlayFromIdent, TheScaleErrorBecomesTheTravelScale) {
  const config::MachineConfig base = config::default_config();
  ident::IdentResult r;
  r.axis = "y";
  r.augmented = ident::preset_axis_model("y");
  r.augmented.set(ident::Effect::kScaleError, true);
  r.augmented.scale = 0.9937;
  r.effects = {ident::Effect::kScaleError};
  auto a = config::apply_calibration_text(base, merge_overlay(base, "", "", r, "fit").value(),
                                          "cal.yaml");
  ASSERT_TRUE(a.ok()) << a.error().to_string();
  EXPECT_DOUBLE_EQ(a.value().config.model.gantry_for("y")->travel_scale, 0.9937);
  ASSERT_EQ(a.value().effects.size(), 1u);
  EXPECT_EQ(a.value().effects[0].name, "scale_error");
  EXPECT_TRUE(a.value().effects[0].in_model);
  r.augmented.scale = 1.25;
  auto far = config::apply_calibration_text(base, merge_overlay(base, "", "", r, "fit").value(),
                                            "cal.yaml");
  ASSERT_TRUE(far.ok());
  EXPECT_EQ(far.value().config.model.gantry_for("y")->travel_scale, 1.0);
  EXPECT_FALSE(far.value().effects[0].in_model);
  auto bad = config::apply_calibration_text(
      base, "calibration_version: 1\nmodel:\n  gantry:\n    y: {travel_scale: 1.3}\n", "cal.yaml");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().to_string().find("travel_scale"), std::string::npos);
}

// The belt the feedforward schedules on comes from the data: uniform at the fitted k2, and the
// named direction ratio (above or below 1) as the belt's own, about that mean; the config's Eq. 6
// geometry (its L) is not the data's and goes.
TEST(OverlayFromIdent, TheBeltIsTheFittedOneUniformWithTheNamedDirectionRatio) {
  const config::MachineConfig base = config::default_config();
  ASSERT_GT(base.model.gantry_for("x")->stepper.belt_unit_stiffness_n, 0.0);  // Eq. 6 by default
  ident::IdentResult r;
  r.axis = "x";
  r.augmented = ident::preset_axis_model("x");
  r.augmented.k2_n_m = 32100.0;
  const auto overlay = [&](const ident::IdentResult& res) {
    auto yaml = merge_overlay(base, "", "", res, "fit");
    EXPECT_TRUE(yaml.ok()) << yaml.error().to_string();
    auto a = config::apply_calibration_text(base, yaml.value(), "cal.yaml");
    EXPECT_TRUE(a.ok()) << a.error().to_string() << "\n" << yaml.value();
    return std::make_pair(*a.value().config.model.gantry_for("x"), a.value().effects);
  };
  const auto lpv = [](const config::GantryModelConfig& g) {
    control::GantryAxisLpvModel m;
    m.params.k2_n_m = g.k2_n_per_m;
    m.belt_unit_stiffness_n = g.stepper.belt_unit_stiffness_n;
    m.pulley_distance_mm = g.stepper.pulley_distance_mm;
    m.direction_ratio = g.belt_direction_ratio;
    return m;
  };
  // None named: k2 in both directions, everywhere.
  const config::GantryModelConfig uniform = overlay(r).first;
  EXPECT_EQ(uniform.stepper.belt_unit_stiffness_n, 0.0);
  EXPECT_EQ(uniform.belt_direction_ratio, 1.0);
  for (double x_mm : {-80.0, 0.0, 100.0})
    for (int dir : {-1, 0, 1})
      EXPECT_DOUBLE_EQ(control::belt_stiffness_n_m(lpv(uniform), x_mm, dir), 32100.0);
  // Named, ratios either side of 1 (0.6 is no Eq. 6 belt at any x > 0): the directions that far
  // apart at every position, their mean the fitted k2, and the effect carried.
  r.augmented.set(ident::Effect::kDirectionStiffness, true);
  r.effects = {ident::Effect::kDirectionStiffness};
  for (double ratio : {1.5, 0.6}) {
    r.augmented.stiffness_ratio = ratio;
    const auto [belt, effects] = overlay(r);
    EXPECT_EQ(belt.stepper.belt_unit_stiffness_n, 0.0);
    EXPECT_DOUBLE_EQ(belt.belt_direction_ratio, ratio);
    const auto m = lpv(belt);
    for (double x_mm : {-80.0, 0.0, 100.0}) {
      EXPECT_NEAR(
          control::belt_stiffness_n_m(m, x_mm, 1) / control::belt_stiffness_n_m(m, x_mm, -1), ratio,
          1e-12);
      EXPECT_NEAR(0.5 * (control::belt_stiffness_n_m(m, x_mm, 1) +
                         control::belt_stiffness_n_m(m, x_mm, -1)),
                  32100.0, 1e-6);
      EXPECT_DOUBLE_EQ(control::belt_stiffness_n_m(m, x_mm, 0), 32100.0);
    }
    ASSERT_EQ(effects.size(), 1u);
    EXPECT_TRUE(effects[0].in_model);
  }
  // A compliance slope along the travel (ident/fit.cpp): written with its reference, and the
  // feedforward's belt is k2 there and k2 / (1 + s (x - x_ref)) elsewhere.
  r.augmented.set(ident::Effect::kDirectionStiffness, false);
  r.effects.clear();
  r.augmented.compliance_slope_per_m = 3.0;
  r.augmented.stiffness_reference_mm = 120.0;
  {
    const config::GantryModelConfig sloped = overlay(r).first;
    EXPECT_DOUBLE_EQ(sloped.belt_compliance_slope_per_m, 3.0);
    EXPECT_DOUBLE_EQ(sloped.belt_stiffness_reference_mm, 120.0);
    control::GantryAxisLpvModel m = lpv(sloped);
    m.compliance_slope_per_m = sloped.belt_compliance_slope_per_m;
    m.stiffness_reference_mm = sloped.belt_stiffness_reference_mm;
    EXPECT_NEAR(control::belt_stiffness_n_m(m, 120.0), 32100.0, 1e-6);
    EXPECT_NEAR(control::belt_stiffness_n_m(m, 170.0), 32100.0 / 1.15, 1e-6);
  }
  r.augmented.compliance_slope_per_m = 0.0;
  EXPECT_EQ(overlay(r).first.belt_stiffness_reference_mm, 0.0);  // no slope, no reference
  auto steep = config::apply_calibration_text(
      base, "calibration_version: 1\nmodel:\n  gantry:\n    x: {belt_compliance_slope_per_m: 60}\n",
      "cal.yaml");
  ASSERT_FALSE(steep.ok());
  EXPECT_NE(steep.error().to_string().find("cal.yaml:4"), std::string::npos)
      << steep.error().to_string();
  // In a hand-written overlay 0 is a uniform belt too; below 0 is an error with its place, and so
  // is a direction ratio beyond 0.1-10.
  auto bad = config::apply_calibration_text(
      base,
      "calibration_version: 1\nmodel:\n  gantry:\n    x: {stepper: {belt_unit_stiffness_n: -1}}\n",
      "cal.yaml");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().to_string().find("cal.yaml:4"), std::string::npos)
      << bad.error().to_string();
  auto bad_ratio = config::apply_calibration_text(
      base, "calibration_version: 1\nmodel:\n  gantry:\n    x: {belt_direction_ratio: 0}\n",
      "cal.yaml");
  ASSERT_FALSE(bad_ratio.ok());
  EXPECT_NE(bad_ratio.error().to_string().find("belt_direction_ratio"), std::string::npos)
      << bad_ratio.error().to_string();
}

// A named runout flows into the model in the fit's own form: its period, sin and cos, and the
// trace's start, from which its phase and the measurement count; the effect is carried.
TEST(OverlayFromIdent, TheRunoutIsCarriedWithThePositionItsPhaseCountsFrom) {
  const config::MachineConfig base = config::default_config();
  ident::IdentResult r;
  r.axis = "x";
  r.start_command_mm = 117.5;
  r.augmented = ident::preset_axis_model("x");
  r.augmented.set(ident::Effect::kPeriodicPosition, true);
  r.augmented.period_mm = 33.9;
  r.augmented.periodic_sin_um = 14.2;
  r.augmented.periodic_cos_um = -6.1;
  r.effects = {ident::Effect::kPeriodicPosition};
  auto yaml = merge_overlay(base, "", "", r, "fit");
  ASSERT_TRUE(yaml.ok()) << yaml.error().to_string();
  auto a = config::apply_calibration_text(base, yaml.value(), "cal.yaml");
  ASSERT_TRUE(a.ok()) << a.error().to_string() << "\n" << yaml.value();
  const config::GantryModelConfig& g = *a.value().config.model.gantry_for("x");
  EXPECT_DOUBLE_EQ(g.runout_period_mm, 33.9);
  EXPECT_DOUBLE_EQ(g.runout_sin_um, 14.2);
  EXPECT_DOUBLE_EQ(g.runout_cos_um, -6.1);
  EXPECT_DOUBLE_EQ(g.runout_reference_mm, 117.5);
  ASSERT_EQ(a.value().effects.size(), 1u);
  EXPECT_TRUE(a.value().effects[0].in_model);
  // calibrate tries it on the machine before it keeps it (the overlay carries it when given).
  EXPECT_TRUE(std::find(effects_tried_on_the_machine().begin(),
                        effects_tried_on_the_machine().end(),
                        ident::Effect::kPeriodicPosition) != effects_tried_on_the_machine().end());
  // None named: no runout, whatever the config had.
  r.augmented.set(ident::Effect::kPeriodicPosition, false);
  r.effects.clear();
  auto none = config::apply_calibration_text(
      base, merge_overlay(base, yaml.value(), "cal.yaml", r, "fit").value(), "cal.yaml");
  ASSERT_TRUE(none.ok());
  EXPECT_EQ(none.value().config.model.gantry_for("x")->runout_period_mm, 0.0);
}

// An identification of the preset X axis that named an extra resonance, carried as fitted.
ident::IdentResult x_axis_with_a_named_mode(double freq_hz, double damping, double mass_kg) {
  ident::IdentResult r;
  r.axis = "x";
  r.augmented = ident::preset_axis_model("x");
  r.augmented.set(ident::Effect::kExtraResonance, true);
  r.augmented.extra_freq_hz = freq_hz;
  r.augmented.extra_damping = damping;
  r.augmented.extra_mass_kg = mass_kg;
  r.effects = {ident::Effect::kExtraResonance};
  r.carried = r.augmented;
  return r;
}

// A named mode (extra_resonance) is in the model the overlay writes: the feedforward's designs
// carry the mass on the carriage (model.gantry.<axis>.extra_resonance_*). A carried model without
// it (identification asked to leave it out, FitOptions::not_carried) records the effect with its
// parameters, in_model false, and writes no mode.
TEST(OverlayFromIdent, TheNamedModeIsInTheModelTheOverlayWrites) {
  EXPECT_EQ(effects_tried_on_the_machine(),
            (std::vector<ident::Effect>{ident::Effect::kPeriodicPosition,
                                        ident::Effect::kExtraResonance}));
  const config::MachineConfig base = config::default_config();
  ident::IdentResult r = x_axis_with_a_named_mode(44.8, 0.04, 0.11);
  r.augmented.k2_n_m = 61000.0;
  r.carried = r.augmented;
  auto yaml = merge_overlay(base, "", "", with_carried_model(r), "fit");
  ASSERT_TRUE(yaml.ok()) << yaml.error().to_string();
  auto a = config::apply_calibration_text(base, yaml.value(), "cal.yaml");
  ASSERT_TRUE(a.ok()) << a.error().to_string() << "\n" << yaml.value();
  const config::GantryModelConfig& g = *a.value().config.model.gantry_for("x");
  EXPECT_EQ(g.k2_n_per_m, 61000.0);
  EXPECT_DOUBLE_EQ(g.extra_resonance_hz, 44.8);
  EXPECT_DOUBLE_EQ(g.extra_resonance_damping, 0.04);
  EXPECT_DOUBLE_EQ(g.extra_resonance_mass_kg, 0.11);
  ASSERT_EQ(a.value().effects.size(), 1u);
  EXPECT_EQ(a.value().effects[0].name, "extra_resonance");
  EXPECT_TRUE(a.value().effects[0].in_model);
  EXPECT_NEAR(a.value().effects[0].params.at("freq_hz"), 44.8, 1e-9);

  // Carried without the mode: recorded only, and the config's mode is cleared.
  r.carried = ident::preset_axis_model("x");
  r.carried.k2_n_m = 52000.0;
  r.carried.extra_freq_hz = 44.8;  // the fit's field, reported, not enabled
  auto yaml2 = merge_overlay(base, yaml.value(), "cal.yaml", with_carried_model(r), "fit");
  ASSERT_TRUE(yaml2.ok()) << yaml2.error().to_string();
  auto b = config::apply_calibration_text(base, yaml2.value(), "cal.yaml");
  ASSERT_TRUE(b.ok()) << b.error().to_string();
  EXPECT_EQ(b.value().config.model.gantry_for("x")->k2_n_per_m, 52000.0);
  EXPECT_EQ(b.value().config.model.gantry_for("x")->extra_resonance_mass_kg, 0.0);
  ASSERT_EQ(b.value().effects.size(), 1u);
  EXPECT_FALSE(b.value().effects[0].in_model);
  EXPECT_NEAR(b.value().effects[0].params.at("freq_hz"), 44.8, 1e-9);
}

// A fitted mode beyond the config's ranges is refused with its key (calibrate then does not try
// it on the machine: the daemon would not reload it).
TEST(OverlayFromIdent, AModeBeyondTheConfigsRangesIsRefusedWithItsKey) {
  const config::MachineConfig base = config::default_config();
  const ident::IdentResult r = x_axis_with_a_named_mode(80.0, 0.05, 500.0);
  auto yaml = merge_overlay(base, "", "", with_carried_model(r), "fit");
  ASSERT_TRUE(yaml.ok()) << yaml.error().to_string();
  auto a = config::apply_calibration_text(base, yaml.value(), "cal.yaml");
  ASSERT_FALSE(a.ok());
  EXPECT_NE(a.error().to_string().find("extra_resonance_mass_kg"), std::string::npos)
      << a.error().to_string();
}

// A mode's mass without its frequency is a located config error, not a feedforward design.
TEST(OverlayFromIdent, AModeWithoutAFrequencyIsRefusedWithItsKey) {
  const config::MachineConfig base = config::default_config();
  const std::string overlay =
      "calibration_version: 1\nmodel:\n  gantry:\n    x:\n      extra_resonance_mass_kg: 0.2\n";
  auto a = config::apply_calibration_text(base, overlay, "cal.yaml");
  ASSERT_FALSE(a.ok());
  EXPECT_NE(a.error().to_string().find("extra_resonance_hz"), std::string::npos)
      << a.error().to_string();
  EXPECT_NE(a.error().to_string().find("cal.yaml"), std::string::npos) << a.error().to_string();
}

}  // namespace
}  // namespace feedloop::calibration
