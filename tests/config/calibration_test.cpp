// Calibration overlays (config/calibration.hpp, config/config_source.hpp): what they change, what
// they leave, round trips, and every kind of bad overlay located in the overlay's own file.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <string>

#include "config/calibration.hpp"
#include "config/config.hpp"
#include "config/config_source.hpp"
#include "tests/config/config_fixture.hpp"

namespace fc = feedloop::config;
using fc::testing::kMinimal;
using fc::testing::pos_of;

namespace {

fc::MachineConfig minimal() {
  auto c = fc::load_config_text(kMinimal, "minimal.yaml");
  EXPECT_TRUE(c.ok()) << (c.ok() ? "" : c.error().to_string());
  return c.ok() ? c.value() : fc::MachineConfig{};
}

// The error text of applying `yaml` (empty when it applied).
std::string problems(const std::string& yaml) {
  auto r = fc::apply_calibration_text(minimal(), yaml, "cal.yaml");
  return r.ok() ? std::string() : r.error().to_string();
}

}  // namespace

TEST(Calibration, ChangesOnlyTheKeysItNames) {
  const fc::MachineConfig base = minimal();
  auto r = fc::apply_calibration_text(base,
                                      "calibration_version: 1\n"
                                      "source: \"test\"\n"
                                      "model:\n"
                                      "  gantry:\n"
                                      "    x: {k1_n_per_m: 298000, coulomb_friction_n: 2.5, friction_bristle_mm: 0.035}\n",
                                      "cal.yaml");
  ASSERT_TRUE(r.ok()) << r.error().to_string();
  const fc::GantryModelConfig* x = r.value().config.model.gantry_for("x");
  ASSERT_NE(x, nullptr);
  EXPECT_EQ(x->k1_n_per_m, 298000.0);
  EXPECT_EQ(x->coulomb_friction_n, 2.5);
  EXPECT_EQ(x->friction_bristle_mm, 0.035);
  // Not named: as the config had them.
  EXPECT_EQ(x->k2_n_per_m, 110e3);
  EXPECT_EQ(x->m2_kg, 0.45);
  EXPECT_EQ(x->stepper, base.model.gantry_for("x")->stepper);
  EXPECT_EQ(r.value().source, "test");
  ASSERT_EQ(r.value().changes.size(), 3u);
  EXPECT_EQ(r.value().changes[0], "model.gantry.x.k1_n_per_m: 355000 -> 298000");
  EXPECT_EQ(r.value().axes, std::vector<std::string>{"x"});
  // Everything outside model.gantry is the config's.
  fc::MachineConfig same = r.value().config;
  same.model = base.model;
  EXPECT_EQ(same, base);
}

TEST(Calibration, AnAxisWithoutAModelNeedsAllSixParameters) {
  const std::string partial = "calibration_version: 1\nmodel:\n  gantry:\n    y: {k1_n_per_m: 4e5}\n";
  const std::string p = problems(partial);
  EXPECT_NE(p.find("cal.yaml:4:"), std::string::npos) << p;
  EXPECT_NE(p.find("m1_kg"), std::string::npos) << p;
  auto r = fc::apply_calibration_text(minimal(),
                                      "calibration_version: 1\nmodel:\n  gantry:\n    y: {m1_kg: 0.13, m2_kg: 1.07, "
                                      "k1_n_per_m: 392e3, k2_n_per_m: 19.7e3, c1_ns_per_m: 411, c2_ns_per_m: 71.5}\n",
                                      "cal.yaml");
  ASSERT_TRUE(r.ok()) << r.error().to_string();
  ASSERT_NE(r.value().config.model.gantry_for("y"), nullptr);
  EXPECT_EQ(r.value().config.model.gantry_for("y")->k2_n_per_m, 19.7e3);
  EXPECT_EQ(r.value().config.model.gantry.size(), 2u);
}

TEST(Calibration, WrittenOverlaysReadBackExactly) {
  fc::Calibration c;
  c.source = "round trip";
  fc::GantryModelConfig x = *minimal().model.gantry_for("x");
  x.k1_n_per_m = 511440.0999757355;
  x.c2_ns_per_m = 129.18684588153752;
  x.coulomb_friction_n = 2.1339782510292524;
  x.friction_bristle_mm = 0.021042795213633364;
  x.stepper.belt_unit_stiffness_n = 37500.92764948901;
  c.gantry.push_back(x);
  c.effects.push_back({"x", "coulomb_friction", {{"force_n", 2.1339782510292524}}, true});
  c.effects.push_back({"x", "periodic_position", {{"period_mm", 33.93}, {"amplitude_um", 20.5}}, false});
  const std::string yaml = fc::calibration_yaml(c);
  auto r = fc::apply_calibration_text(minimal(), yaml, "cal.yaml");
  ASSERT_TRUE(r.ok()) << r.error().to_string() << "\n" << yaml;
  EXPECT_EQ(*r.value().config.model.gantry_for("x"), x);
  ASSERT_EQ(r.value().effects.size(), 2u);
  EXPECT_EQ(r.value().effects[1].name, "periodic_position");
  EXPECT_EQ(r.value().effects[1].params.at("amplitude_um"), 20.5);
  EXPECT_FALSE(r.value().effects[1].in_model);
  EXPECT_TRUE(r.value().effects[0].in_model);
  EXPECT_EQ(r.value().source, "round trip");
}

TEST(Calibration, EveryProblemIsReportedAtItsPlaceAndNothingApplies) {
  const std::string y =
      "calibration_version: 1\n"
      "model:\n"
      "  gantry:\n"
      "    x: {k1_n_per_m: -5, k3_n_per_m: 2, friction_bristle_mm: 7}\n"
      "    q: {m1_kg: 1}\n"
      "effects:\n"
      "  - {axis: w, name: backlash, params: {width_um: zero}}\n"
      "extra: 1\n";
  const std::string p = problems(y);
  const auto at = [&](const std::string& needle) {
    const fc::testing::Pos q = pos_of(y, needle);
    return "cal.yaml:" + std::to_string(q.line) + ":" + std::to_string(q.column);
  };
  EXPECT_NE(p.find(at("-5") + ": model.gantry.x.k1_n_per_m must be in [100, 1e+10] N/m"),
            std::string::npos)
      << p;
  EXPECT_NE(p.find(at("k3_n_per_m") + ": unknown key 'k3_n_per_m'"), std::string::npos) << p;
  EXPECT_NE(p.find(at("7}") + ": model.gantry.x.friction_bristle_mm"), std::string::npos) << p;
  EXPECT_NE(p.find(at("q:") + ": model.gantry: 'q' is not an axis"), std::string::npos) << p;
  EXPECT_NE(p.find("'w' is not an axis of the config"), std::string::npos) << p;
  EXPECT_NE(p.find(at("zero")), std::string::npos) << p;
  EXPECT_NE(p.find(at("extra") + ": unknown key 'extra'"), std::string::npos) << p;
}

TEST(Calibration, WrongFilesAreClearErrors) {
  EXPECT_NE(problems("").find("the calibration file is empty"), std::string::npos);
  EXPECT_NE(problems("model: {}\n").find("calibration_version"), std::string::npos);
  EXPECT_NE(problems("calibration_version: 2\n").find("calibration_version 2 is not supported"), std::string::npos);
  EXPECT_NE(problems("calibration_version: 1\nmodel: [\n").find("cal.yaml:"), std::string::npos);
  EXPECT_NE(problems("calibration_version: 1\nsource: \"\xff\"\n").find("cal.yaml:2:10: the file is not valid UTF-8"),
            std::string::npos);
  EXPECT_NE(problems("- a\n- b\n").find("cal.yaml:1:1"), std::string::npos);
  EXPECT_NE(problems("calibration_version: 1\nmodel:\n  gantry:\n    x: {k1_n_per_m: 1e400}\n").find("cal.yaml:4:"),
            std::string::npos);
  // A delta has no gantry model to calibrate.
  auto delta = fc::load_config_file(FEEDLOOP_SOURCE_DIR "/config/examples/delta_sim.yaml");
  ASSERT_TRUE(delta.ok()) << delta.error().to_string();
  auto r = fc::apply_calibration_text(delta.value(), "calibration_version: 1\nmodel:\n  gantry:\n    x: {m1_kg: 1}\n",
                                      "cal.yaml");
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().to_string().find("a delta uses model.delta_lpv"), std::string::npos);
}

// control.axes.<axis>: the PI gains `feedloop calibrate` chose; the other axes keep the config's.
TEST(Calibration, PiGainsPerAxisOverTheConfigsAndBackExactly) {
  const fc::MachineConfig base = minimal();
  auto r = fc::apply_calibration_text(base,
                                      "calibration_version: 1\n"
                                      "model:\n  gantry:\n    x: {k1_n_per_m: 298000}\n"
                                      "control:\n  axes:\n    x: {kp: 0.125, ki_per_s: 5}\n",
                                      "cal.yaml");
  ASSERT_TRUE(r.ok()) << r.error().to_string();
  const fc::ControlConfig& c = r.value().config.control;
  EXPECT_EQ(c.gains_for("x").kp, 0.125);
  EXPECT_EQ(c.gains_for("x").ki_per_s, 5.0);
  EXPECT_EQ(c.gains_for("y").kp, base.control.gains_for("y").kp);
  EXPECT_EQ(c.gains_for("y").ki_per_s, base.control.gains_for("y").ki_per_s);
  ASSERT_EQ(r.value().gains.size(), 1u);
  const std::vector<std::string>& ch = r.value().changes;
  EXPECT_NE(std::find(ch.begin(), ch.end(), "control.axes.x.kp: 0.5 -> 0.125"), ch.end());
  EXPECT_NE(std::find(ch.begin(), ch.end(), "control.axes.x.ki_per_s: 20 -> 5"), ch.end());

  // Written and read back: the same gains.
  fc::Calibration cal;
  cal.source = "gains";
  cal.gantry.push_back(*r.value().config.model.gantry_for("x"));
  cal.gains = {{"x", 0.1234567890123, 2.5}, {"y", 0.0, 0.0}};
  const std::string yaml = fc::calibration_yaml(cal);
  auto back = fc::apply_calibration_text(base, yaml, "cal.yaml");
  ASSERT_TRUE(back.ok()) << back.error().to_string() << "\n" << yaml;
  EXPECT_EQ(back.value().config.control.gains_for("x").kp, 0.1234567890123);
  EXPECT_EQ(back.value().config.control.gains_for("y").kp, 0.0);
  EXPECT_EQ(back.value().config.control.gains_for("y").ki_per_s, 0.0);

  // Bad gains are located and nothing applies.
  const std::string bad =
      "calibration_version: 1\ncontrol:\n  axes:\n    x: {kp: -1, gain: 2}\n    w: {kp: 1}\n";
  const std::string p = problems(bad);
  EXPECT_NE(p.find("cal.yaml:4:"), std::string::npos) << p;
  EXPECT_NE(p.find("unknown key 'gain'"), std::string::npos) << p;
  EXPECT_NE(p.find("'w' is not an axis of the config"), std::string::npos) << p;
}

TEST(ConfigSource, TheDefaultOverlayIsOptionalAnExplicitOneIsNot) {
  const std::string dir = ::testing::TempDir();
  const std::string path = dir + "/calibration_source_test.yaml";
  std::remove(path.c_str());
  auto none = fc::load_machine_config({"", path, false});
  ASSERT_TRUE(none.ok()) << none.error().to_string();
  EXPECT_TRUE(none.value().calibration.empty());
  EXPECT_EQ(none.value().config, fc::default_config());
  auto missing = fc::load_machine_config({"", path, true});
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().to_string().find("cannot read calibration file"), std::string::npos);

  std::ofstream(path) << "calibration_version: 1\nmodel:\n  gantry:\n    y: {coulomb_friction_n: 1.5}\n";
  auto with = fc::load_machine_config({"", path, false});
  ASSERT_TRUE(with.ok()) << with.error().to_string();
  EXPECT_EQ(with.value().calibration, path);
  EXPECT_EQ(with.value().config.model.gantry_for("y")->coulomb_friction_n, 1.5);
  ASSERT_EQ(with.value().changes.size(), 1u);
  EXPECT_EQ(with.value().changes[0], "model.gantry.y.coulomb_friction_n: 0 -> 1.5");
  std::remove(path.c_str());
}
