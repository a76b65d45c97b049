// What the calibration overlay takes from a fit (calibration/overlay_from_ident.hpp).
#include "calibration/overlay_from_ident.hpp"

#include <gtest/gtest.h>

#include "config/config.hpp"
#include "control/feedforward/gantry_lpv.hpp"

#include <cmath>

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

TEST(BeltLength, FromTheDirectionRatioOnlyWhenTheBeltSpansTheTravel) {
  // K2(+)/K2(-) = (L + x)/(L - x): L = x (r + 1)/(r - 1).
  EXPECT_NEAR(belt_length_from_direction_ratio(1.5, 70.0, 150.0), 350.0, 1e-9);
  EXPECT_EQ(belt_length_from_direction_ratio(1.01, 70.0, 150.0), 0.0);  // no ratio to speak of
  EXPECT_EQ(belt_length_from_direction_ratio(3.0, 70.0, 150.0), 0.0);   // L 140 < the travel
  EXPECT_EQ(belt_length_from_direction_ratio(NAN, 70.0, 150.0), 0.0);
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
  auto yaml = merge_overlay(base, "", "", r, 100.0, "fit");
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
  auto none = config::apply_calibration_text(
      base, merge_overlay(base, "", "", r, 100.0, "fit").value(), "cal.yaml");
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

// The belt the feedforward schedules on (Eq. 6) comes from the data: a uniform belt at the fitted
// k2 when no direction-dependent stiffness is named (the config's L was an assumption), L from the
// ratio when one is named and gives a belt beyond the travel, the config's L otherwise.
TEST(OverlayFromIdent, TheBeltIsUniformUnlessTheDataShowsADirection) {
  const config::MachineConfig base = config::default_config();
  ASSERT_GT(base.model.gantry_for("x")->stepper.belt_unit_stiffness_n, 0.0);  // Eq. 6 by default
  ident::IdentResult r;
  r.axis = "x";
  r.augmented = ident::preset_axis_model("x");
  r.augmented.k2_n_m = 32100.0;
  const auto overlay = [&](const ident::IdentResult& res) {
    auto yaml = merge_overlay(base, "", "", res, 100.0, "fit");
    EXPECT_TRUE(yaml.ok()) << yaml.error().to_string();
    auto a = config::apply_calibration_text(base, yaml.value(), "cal.yaml");
    EXPECT_TRUE(a.ok()) << a.error().to_string() << "\n" << yaml.value();
    return *a.value().config.model.gantry_for("x");
  };
  const auto lpv = [](const config::GantryModelConfig& g) {
    control::GantryAxisLpvModel m;
    m.params.k2_n_m = g.k2_n_per_m;
    m.belt_unit_stiffness_n = g.stepper.belt_unit_stiffness_n;
    m.pulley_distance_mm = g.stepper.pulley_distance_mm;
    return m;
  };
  // None named: k2 in both directions, everywhere.
  const config::GantryModelConfig uniform = overlay(r);
  EXPECT_EQ(uniform.stepper.belt_unit_stiffness_n, 0.0);
  for (double x_mm : {-80.0, 0.0, 100.0})
    for (int dir : {-1, 0, 1})
      EXPECT_DOUBLE_EQ(control::belt_stiffness_n_m(lpv(uniform), x_mm, dir), 32100.0);
  // Named, ratio 1.5 at the trace's mean 100 mm: L = 500 mm, the directions 1.5 apart there,
  // their mean the fitted k2.
  r.augmented.set(ident::Effect::kDirectionStiffness, true);
  r.augmented.stiffness_ratio = 1.5;
  r.effects = {ident::Effect::kDirectionStiffness};
  const config::GantryModelConfig belt = overlay(r);
  EXPECT_NEAR(belt.stepper.pulley_distance_mm, 500.0, 1e-9);
  const auto m = lpv(belt);
  EXPECT_NEAR(control::belt_stiffness_n_m(m, 100.0, 1) / control::belt_stiffness_n_m(m, 100.0, -1),
              1.5, 1e-9);
  EXPECT_NEAR(control::belt_stiffness_n_m(m, 100.0, 0), 32100.0, 1e-6);
  // Named, but a ratio no belt beyond the travel gives (L = 200 mm at ratio 3): the config's L,
  // k-hat scaled so that the mean is the fitted k2 at 100 mm.
  r.augmented.stiffness_ratio = 3.0;
  const config::GantryModelConfig kept = overlay(r);
  EXPECT_EQ(kept.stepper.pulley_distance_mm,
            base.model.gantry_for("x")->stepper.pulley_distance_mm);
  EXPECT_GT(kept.stepper.belt_unit_stiffness_n, 0.0);
  EXPECT_NEAR(control::belt_stiffness_n_m(lpv(kept), 100.0, 0), 32100.0, 1e-6);
  // In a hand-written overlay 0 is a uniform belt too; below 0 is an error with its place.
  auto bad = config::apply_calibration_text(
      base,
      "calibration_version: 1\nmodel:\n  gantry:\n    x: {stepper: {belt_unit_stiffness_n: -1}}\n",
      "cal.yaml");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().to_string().find("cal.yaml:4"), std::string::npos)
      << bad.error().to_string();
}

// The overlay writes the carried model (identification's model without the effects the
// feedforward does not carry), and still records the effects left out, with their parameters.
TEST(OverlayFromIdent, TheOverlayWritesTheModelTheFeedforwardCarries) {
  const config::MachineConfig base = config::default_config();
  ident::IdentResult r;
  r.axis = "x";
  r.augmented = ident::preset_axis_model("x");
  r.augmented.k2_n_m = 61000.0;
  r.augmented.set(ident::Effect::kExtraResonance, true);
  r.augmented.extra_freq_hz = 44.8;
  r.effects = {ident::Effect::kExtraResonance};
  r.carried = ident::preset_axis_model("x");
  r.carried.k2_n_m = 52000.0;
  r.carried.extra_freq_hz = 44.8;
  auto yaml = merge_overlay(base, "", "", with_carried_model(r), 100.0, "fit");
  ASSERT_TRUE(yaml.ok()) << yaml.error().to_string();
  auto a = config::apply_calibration_text(base, yaml.value(), "cal.yaml");
  ASSERT_TRUE(a.ok()) << a.error().to_string();
  EXPECT_EQ(a.value().config.model.gantry_for("x")->k2_n_per_m, 52000.0);
  ASSERT_EQ(a.value().effects.size(), 1u);
  EXPECT_EQ(a.value().effects[0].name, "extra_resonance");
  EXPECT_FALSE(a.value().effects[0].in_model);
  EXPECT_NEAR(a.value().effects[0].params.at("freq_hz"), 44.8, 1e-9);
  for (ident::Effect e : effects_not_in_model())
    EXPECT_TRUE(e == ident::Effect::kPeriodicPosition || e == ident::Effect::kExtraResonance ||
                e == ident::Effect::kScaleError);
}

}  // namespace
}  // namespace feedloop::calibration
