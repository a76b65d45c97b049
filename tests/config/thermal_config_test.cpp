// The heaters: and fans: sections: defaults by kind, custom thermistors, and every problem with its
// file:line:column (an unknown sensor, an implausible max_temp_c, a range the sensor cannot read, a
// heater fan without its heater).
#include <gtest/gtest.h>

#include <string>

#include "config/config.hpp"
#include "config_fixture.hpp"

namespace feedloop::config {
namespace {

using testing::kMinimal;
using testing::Pos;
using testing::pos_of;

std::string with(const std::string& tail) {
  return std::string(kMinimal) + tail;
}

void expect_error(const std::string& yaml, const std::string& text, Pos at) {
  const std::vector<Error> errors = check_config_text(yaml, "printer.yaml");
  ASSERT_FALSE(errors.empty()) << yaml;
  const Error* hit = nullptr;
  for (const Error& e : errors)
    if (e.message.find(text) != std::string::npos) hit = &e;
  ASSERT_NE(hit, nullptr) << "no problem mentions '" << text
                          << "'; first: " << errors[0].to_string();
  EXPECT_EQ(hit->where.line, at.line) << hit->to_string();
  EXPECT_EQ(hit->where.column, at.column) << hit->to_string();
}

TEST(ThermalConfig, DefaultsByKindAndACustomThermistor) {
  const std::string yaml = with(
      "heaters:\n"
      "  extruder: {kind: extruder, sensor: Semitec 104GT-2, max_temp_c: 285}\n"
      "  bed: {kind: bed}\n"
      "  chamber:\n"
      "    kind: chamber\n"
      "    sensor: thermistor\n"
      "    thermistor: {form: beta, t1_c: 25, r1_ohm: 100000, beta: 3950}\n"
      "    max_temp_c: 80\n"
      "fans:\n"
      "  part: {kind: part}\n"
      "  hotend_fan: {kind: heater, heater: extruder}\n");
  auto cfg = load_config_text(yaml, "printer.yaml");
  ASSERT_TRUE(cfg.ok()) << cfg.error().to_string();
  ASSERT_EQ(cfg->heaters.size(), 3u);
  EXPECT_EQ(cfg->heaters[0].name, "extruder");
  EXPECT_EQ(cfg->heaters[0].pid_kp, 22.2);
  EXPECT_EQ(cfg->heaters[1].max_temp_c, 120.0);  // the bed's default
  EXPECT_EQ(cfg->heaters[1].pid_kp, 97.1);
  EXPECT_EQ(cfg->heaters[1].protection.runaway_period_s, 20.0);
  ASSERT_TRUE(cfg->heaters[2].thermistor);
  EXPECT_EQ(cfg->heaters[2].thermistor->beta, 3950.0);
  ASSERT_EQ(cfg->fans.size(), 2u);
  EXPECT_EQ(cfg->fans[1].heater, "extruder");
  // to_yaml round-trips the sections.
  auto again = load_config_text(to_yaml(*cfg), "again.yaml");
  ASSERT_TRUE(again.ok()) << again.error().to_string();
  EXPECT_EQ(again->heaters, cfg->heaters);
  EXPECT_EQ(again->fans, cfg->fans);
}

TEST(ThermalConfig, TheEmbeddedDefaultHasAnExtruderABedAndAPartFan) {
  const MachineConfig& c = default_config();
  ASSERT_EQ(c.heaters.size(), 2u);
  EXPECT_EQ(c.heaters[0].kind, HeaterKind::extruder);
  EXPECT_EQ(c.heaters[1].kind, HeaterKind::bed);
  ASSERT_GE(c.fans.size(), 1u);
  EXPECT_EQ(c.fans[0].kind, FanKind::part);
}

TEST(ThermalConfig, ProblemsCarryTheirLocation) {
  {
    const std::string y = with("heaters:\n  extruder: {kind: extruder, sensor: NTC 42}\n");
    expect_error(y, "unknown sensor 'NTC 42'", pos_of(y, "NTC 42"));
  }
  {
    const std::string y = with("heaters:\n  extruder: {kind: extruder, max_temp_c: 600}\n");
    expect_error(y, "implausible for a heater of kind extruder", pos_of(y, "600"));
  }
  {
    const std::string y = with("heaters:\n  bed:\n    kind: bed\n    max_temp_c: 180\n");
    expect_error(y, "at most 150 C", pos_of(y, "max_temp_c: 180", 12));
  }
  {  // an EPCOS 100K on 4.7k reads 480 C as a fraction of 0.0035: indistinguishable from a short
    const std::string y = with("heaters:\n  extruder:\n    kind: extruder\n    max_temp_c: 480\n");
    expect_error(y, "indistinguishable from a short", pos_of(y, "max_temp_c"));
  }
  {
    const std::string y = with(
        "heaters:\n  extruder:\n    kind: extruder\n    min_temp_c: 300\n    max_temp_c: 250\n");
    expect_error(y, "must be below max_temp_c", pos_of(y, "min_temp_c"));
  }
  {
    const std::string y =
        with("heaters:\n  e0: {kind: extruder}\nfans:\n  hf: {kind: heater, heater: e1}\n");
    expect_error(y, "no heater named 'e1'", pos_of(y, "e1"));
  }
  {
    const std::string y = with("heaters:\n  e0: {kind: extruder, pid: {kp: -1}}\n");
    expect_error(y, "kp", pos_of(y, "-1"));
  }
  {
    const std::string y =
        with("heaters:\n  e0: {kind: extruder, protection: {runaway_perod_s: 10}}\n");
    expect_error(y, "runaway_perod_s", pos_of(y, "runaway_perod_s"));
  }
}

}  // namespace
}  // namespace feedloop::config
