// The residual loop on simulated data with effects the identification is not told about: each
// effect of the vocabulary alone, two at once, and none, on the thesis's X and Y axes. Checks the
// effect names, parameters within 25 %, the residual RMS at most halved, nothing for clean data.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>

#include "ident/excitation.hpp"
#include "ident/fit.hpp"
#include "sim/experiments/gantry_recording.hpp"

namespace feedloop::ident {
namespace {

struct Case {
  std::string name;
  char axis;  // 'x' or 'y'
  sim::GantryEffects effects;
  bool belt_direction = false;  // belt_x0 = 100 mm: K2 pulling + / pulling - = 450 / 250 = 1.8
  std::map<std::string, std::map<std::string, double>> expect;  // effect -> param -> value
};

sim::GantryAxisParams plant_for(const Case& c) {
  sim::GantryAxisParams p = c.axis == 'x' ? sim::thesis_x_axis() : sim::thesis_y_axis();
  p.belt_span_mm = 1e6;  // the linear model's belt everywhere (docs/simulator.md)
  if (c.belt_direction) {
    p.belt_span_mm = 350.0;
    p.belt_x0_mm = 100.0;
  }
  p.effects = c.effects;
  p.seed = 7;
  return p;
}

double param_of(const AxisModel& m, const std::string& effect, const std::string& param) {
  if (effect == "periodic_position") return param == "period_mm" ? m.period_mm : m.periodic_amplitude_um();
  if (effect == "coulomb_friction") return m.friction_force_n;
  if (effect == "backlash") return m.backlash_width_um;
  if (effect == "direction_dependent_stiffness") return m.stiffness_ratio;
  if (effect == "extra_resonance") return param == "freq_hz" ? m.extra_freq_hz : m.extra_damping;
  if (effect == "time_delay") return m.delay_ms;
  if (effect == "scale_error") return m.scale;
  return NAN;
}

std::vector<Case> cases() {
  std::vector<Case> out;
  for (char axis : {'x', 'y'}) {
    const std::string a(1, axis);
    Case clean{a + "_none", axis, {}, false, {}};
    out.push_back(clean);
    Case per{a + "_periodic", axis, {}, false, {{"periodic_position", {{"period_mm", 33.93}, {"amplitude_um", 15.0}}}}};
    per.effects.periodic_position = {true, 33.93, 15.0};
    out.push_back(per);
    Case fr{a + "_friction", axis, {}, false, {{"coulomb_friction", {{"force_n", 2.0}}}}};
    fr.effects.coulomb_friction = {true, 2.0};
    out.push_back(fr);
    Case bl{a + "_backlash", axis, {}, false, {{"backlash", {{"width_um", 30.0}}}}};
    bl.effects.backlash = {true, 30.0};
    out.push_back(bl);
    Case ds{a + "_direction", axis, {}, true, {{"direction_dependent_stiffness", {{"ratio", 1.8}}}}};
    out.push_back(ds);
    Case er{a + "_resonance", axis, {}, false, {{"extra_resonance", {{"freq_hz", 35.0}, {"damping", 0.05}}}}};
    er.effects.extra_resonance = {true, 35.0, 0.05, 0.15};
    out.push_back(er);
    Case td{a + "_delay", axis, {}, false, {{"time_delay", {{"delay_ms", 5.0}}}}};
    td.effects.time_delay = {true, 5.0};
    out.push_back(td);
    Case sc{a + "_scale", axis, {}, false, {{"scale_error", {{"scale", 1.003}}}}};
    sc.effects.scale_error = {true, 1.003};
    out.push_back(sc);
    Case two{a + "_periodic_backlash", axis, {}, false,
             {{"periodic_position", {{"period_mm", 33.93}, {"amplitude_um", 15.0}}}, {"backlash", {{"width_um", 30.0}}}}};
    two.effects.periodic_position = {true, 33.93, 15.0};
    two.effects.backlash = {true, 30.0};
    out.push_back(two);
    Case two2{a + "_delay_scale", axis, {}, false, {{"time_delay", {{"delay_ms", 5.0}}}, {"scale_error", {{"scale", 1.003}}}}};
    two2.effects.time_delay = {true, 5.0};
    two2.effects.scale_error = {true, 1.003};
    out.push_back(two2);
  }
  return out;
}

class EffectCase : public ::testing::TestWithParam<Case> {};

// The case's plant driven by `command` (mm at 1 kHz), recorded and identified.
Result<IdentResult> identify_on(const Case& c, const std::vector<double>& command) {
  auto trace = sim::record_gantry_trace(plant_for(c), command, 1000.0, std::string(1, c.axis));
  if (!trace.ok()) return trace.error();
  const AxisTrace& a = trace.value().axes[0];
  return identify_axis(a.name, a.cmd_mm, a.meas_mm, trace.value().period_s(), FitOptions{});
}

// 30 s of random moves recorded on the case's plant, identified.
Result<IdentResult> identify_case(const Case& c) {
  RandomMovesOptions ro;
  ro.duration_s = 30.0;
  ro.seed = 11;
  if (c.belt_direction) ro.travel_mm = 0.0;
  return identify_on(c, random_moves(ro));
}

// The RMS the clean trace of the axis leaves after its fit (once per axis and process).
double clean_floor_um(char axis) {
  static std::map<char, double> floor;
  if (const auto it = floor.find(axis); it != floor.end()) return it->second;
  auto r = identify_case(Case{std::string(1, axis) + "_none", axis, {}, false, {}});
  EXPECT_TRUE(r.ok());
  return floor[axis] = r.ok() ? r.value().augmented_rms_um : 0.0;
}

TEST_P(EffectCase, FindsExactlyTheEffectsThatArePresent) {
  const Case& c = GetParam();
  auto r = identify_case(c);
  ASSERT_TRUE(r.ok()) << r.error().to_string();
  const IdentResult& res = r.value();
  std::string found;
  for (Effect e : res.effects) found += std::string(effect_name(e)) + " ";
  std::printf("%-22s baseline %.3f um (val %.3f)  augmented %.3f um (val %.3f)  found: %s\n", c.name.c_str(),
              res.baseline_rms_um, res.baseline_validation_rms_um, res.augmented_rms_um,
              res.augmented_validation_rms_um, found.c_str());
  for (const auto& cand : res.candidates)
    std::printf("    round %d %-30s val %.3f%s\n", cand.round, effect_name(cand.effect), cand.validation_rms_um,
                cand.kept ? "  kept" : "");
  for (Effect e : res.effects) {
    std::printf("    found %s:", effect_name(e));
    std::printf(" k1 %.0f k2 %.0f c1 %.1f c2 %.1f", res.augmented.k1_n_m, res.augmented.k2_n_m, res.augmented.c1_n_s_m,
                res.augmented.c2_n_s_m);
    std::printf(" per %.3f/%.3f fc %.3f bl %.3f r %.3f f %.2f z %.3f d %.3f s %.6f\n", res.augmented.period_mm,
                res.augmented.periodic_amplitude_um(), res.augmented.friction_force_n, res.augmented.backlash_width_um,
                res.augmented.stiffness_ratio, res.augmented.extra_freq_hz, res.augmented.extra_damping,
                res.augmented.delay_ms, res.augmented.scale);
  }
  ASSERT_EQ(res.effects.size(), c.expect.size()) << found;
  for (Effect e : res.effects) {
    const auto it = c.expect.find(effect_name(e));
    ASSERT_NE(it, c.expect.end()) << "unexpected effect " << effect_name(e);
    for (const auto& [param, want] : it->second) {
      const double got = param_of(res.augmented, it->first, param);
      std::printf("    %s.%s = %.5g (true %.5g)\n", it->first.c_str(), param.c_str(), got, want);
      if (param == "scale")
        EXPECT_NEAR(got - 1.0, want - 1.0, 0.25 * std::abs(want - 1.0)) << param;
      else
        EXPECT_NEAR(got, want, 0.25 * std::abs(want)) << param;
    }
  }
  if (!c.expect.empty()) {
    // The effect explains what it adds: the RMS halves, or falls to what the clean trace of the
    // axis leaves (the recorded command is a step count: its rounding leaves 1.4-1.8 um).
    EXPECT_LE(res.augmented_rms_um,
              std::max(0.5 * res.baseline_rms_um, 1.05 * clean_floor_um(c.axis)));
  }
}

// The whole matrix (20 cases, ~2.5 min optimized) is the `slow` binary ident_effects_matrix_test;
// the quick binary runs clean data and two effects at once.
std::vector<Case> selected_cases() {
#ifdef IDENT_FULL_MATRIX
  return cases();
#else
  std::vector<Case> out;
  for (const Case& c : cases())
    if (c.name == "x_none" || c.name == "y_periodic_backlash") out.push_back(c);
  return out;
#endif
}

INSTANTIATE_TEST_SUITE_P(Gantry, EffectCase, ::testing::ValuesIn(selected_cases()),
                         [](const ::testing::TestParamInfo<Case>& i) { return i.param.name; });

#ifndef IDENT_FULL_MATRIX
// Dead bands on the thesis's X axis through the calibration program that `feedloop calibrate`
// runs: 120 um (the top of the second simulator's drawn widths; the first simulator draws 15-60)
// and 300 um (a loose pulley). Each is named a backlash, its width within 25 %. Before the width's
// first guess was read off the trace's slides, 200 and 300 um bands were named a friction of
// 5-6 N on a belt of half the stiffness (docs/ident.md, "Friction against backlash").
TEST(EffectBounds, DeadBandsUpToALoosePulleyAreNamedBacklash) {
  for (const double width_um : {120.0, 300.0}) {
    Case c{"x_wide_backlash", 'x', {}, false, {}};
    c.effects.backlash = {true, width_um};
    CalibrationProgramOptions o;
    o.seed = 11;
    auto r = identify_on(c, calibration_program(o));
    ASSERT_TRUE(r.ok()) << r.error().to_string();
    const IdentResult& res = r.value();
    std::printf("%.0f um drawn: %zu effect(s), width %.2f um, held out %.2f -> %.2f um\n", width_um,
                res.effects.size(), res.augmented.backlash_width_um, res.baseline_validation_rms_um,
                res.augmented_validation_rms_um);
    ASSERT_EQ(res.effects.size(), 1u) << width_um;
    EXPECT_EQ(res.effects[0], Effect::kBacklash) << width_um;
    EXPECT_NEAR(res.augmented.backlash_width_um, width_um, 0.25 * width_um);
    EXPECT_LT(res.augmented_validation_rms_um, 0.1 * res.baseline_validation_rms_um);
  }
}
#endif

}  // namespace
}  // namespace feedloop::ident
