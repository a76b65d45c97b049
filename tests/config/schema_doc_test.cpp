// Every key the config writes is documented in config/README.md, per-axis shaper overrides work,
// and changed_sections() agrees with operator== (so a field added later cannot be missed by it).
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cctype>
#include <set>

#include "config/config.hpp"
#include "config/diff.hpp"
#include "config_fixture.hpp"

namespace feedloop::config {
namespace {

bool is_word_char(char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; }

// `key` as a whole word somewhere in `doc`.
bool documented(const std::string& doc, const std::string& key) {
  for (std::size_t at = doc.find(key); at != std::string::npos; at = doc.find(key, at + 1)) {
    const bool left = at == 0 || !is_word_char(doc[at - 1]);
    const bool right = at + key.size() >= doc.size() || !is_word_char(doc[at + key.size()]);
    if (left && right) return true;
  }
  return false;
}

void collect_keys(const YAML::Node& n, std::set<std::string>& keys) {
  if (n.IsMap()) {
    for (auto it = n.begin(); it != n.end(); ++it) {
      keys.insert(it->first.Scalar());
      collect_keys(it->second, keys);
    }
  } else if (n.IsSequence()) {
    for (const YAML::Node& item : n) collect_keys(item, keys);
  }
}

// A config that uses every optional section.
std::string full_yaml() {
  std::string y = testing::kMinimal;
  y += "feedforward:\n  type: shaper\n  shaper:\n    type: ei\n    freq_hz: 45\n"
       "    axes:\n      x: {freq_hz: 48}\n      y: {freq_hz: 31, type: zv, damping: 0.05}\n"
       "simulator:\n  effects:\n"
       "    coulomb_friction: {force_n: 1.5}\n    backlash: {width_um: 25}\n"
       "    periodic_position: {period_mm: 33.9, amplitude_um: 25}\n"
       "    direction_dependent_stiffness: {ratio: 1.4}\n"
       "    extra_resonance: {freq_hz: 95, damping: 0.03}\n    time_delay: {delay_ms: 1.5}\n"
       "    scale_error: {scale: 1.003, axes: [y]}\n"
       "control:\n  kp: 0.6\n  axes:\n    x: {kp: 1.0}\n    y: {kp: 0.75, ki_per_s: 10}\n";
  y = testing::edit(y, "      c2_ns_per_m: 112\n", "      c2_ns_per_m: 112\n      coulomb_friction_n: 1.8\n");
  y = testing::edit(y, "  - name: mcu_e\n    axes: [e]\n    transport: mock\n",
                    "  - name: mcu_e\n    axes: [e]\n    transport: serial\n"
                    "    serial: {device: /dev/ttyACM0}\n");
  y = testing::edit(y, "  - name: mcu_z\n    axes: [z]\n    transport: mock\n",
                    "  - name: mcu_z\n    axes: [z]\n    transport: usb\n"
                    "    usb: {vid: 0x1209, pid: 0x0001}\n");
  return y;
}

TEST(ConfigSchemaDoc, EveryWrittenKeyIsInTheReadme) {
  const std::string readme =
      testing::read_text(std::string(FEEDLOOP_SOURCE_DIR) + "/config/README.md");
  ASSERT_FALSE(readme.empty());
  std::set<std::string> keys;
  Result<MachineConfig> cart = load_config_text(full_yaml(), "full.yaml");
  ASSERT_TRUE(cart.ok()) << cart.error().to_string();
  collect_keys(YAML::Load(to_yaml(*cart)), keys);
  Result<MachineConfig> delta = load_config_file(testing::example_path("delta_sim.yaml"));
  ASSERT_TRUE(delta.ok());
  collect_keys(YAML::Load(to_yaml(*delta)), keys);
  EXPECT_GT(keys.size(), 120u);
  for (const std::string& k : keys) EXPECT_TRUE(documented(readme, k)) << "undocumented key: " << k;
}

TEST(ConfigShaper, PerAxisOverridesInheritTheCommonValues) {
  Result<MachineConfig> r = load_config_text(full_yaml(), "full.yaml");
  ASSERT_TRUE(r.ok()) << r.error().to_string();
  const ShaperConfig& s = r->feedforward.shaper;
  const AxisShaperConfig x = s.for_axis("x"), y = s.for_axis("y"), z = s.for_axis("z");
  EXPECT_EQ(x.type, ShaperType::ei);  // inherited
  EXPECT_DOUBLE_EQ(x.freq_hz, 48.0);
  EXPECT_DOUBLE_EQ(x.damping, 0.1);   // inherited default
  EXPECT_EQ(y.type, ShaperType::zv);
  EXPECT_DOUBLE_EQ(y.freq_hz, 31.0);
  EXPECT_DOUBLE_EQ(y.damping, 0.05);
  EXPECT_DOUBLE_EQ(z.freq_hz, 45.0);  // no override: the common values
  Result<MachineConfig> back = load_config_text(to_yaml(*r), "roundtrip");
  ASSERT_TRUE(back.ok()) << back.error().to_string();
  EXPECT_TRUE(*back == *r);
}

TEST(ConfigControl, PerAxisGainsInheritTheCommonValues) {
  Result<MachineConfig> r = load_config_text(full_yaml(), "full.yaml");
  ASSERT_TRUE(r.ok()) << r.error().to_string();
  const ControlConfig& c = r->control;
  EXPECT_DOUBLE_EQ(c.gains_for("x").kp, 1.0);
  EXPECT_DOUBLE_EQ(c.gains_for("x").ki_per_s, 20.0);  // inherited default
  EXPECT_DOUBLE_EQ(c.gains_for("y").kp, 0.75);
  EXPECT_DOUBLE_EQ(c.gains_for("y").ki_per_s, 10.0);
  EXPECT_DOUBLE_EQ(c.gains_for("z").kp, 0.6);  // no override: the common values
  EXPECT_DOUBLE_EQ(r->model.gantry_for("x")->coulomb_friction_n, 1.8);
  Result<MachineConfig> back = load_config_text(to_yaml(*r), "roundtrip");
  ASSERT_TRUE(back.ok()) << back.error().to_string();
  EXPECT_TRUE(*back == *r);
  const std::string bad = std::string(testing::kMinimal) + "control:\n  axes:\n    q: {kp: 1}\n    x: {kp: -1}\n";
  const std::vector<Error> errors = check_config_text(bad, "c.yaml");
  ASSERT_EQ(errors.size(), 2u);
  EXPECT_NE(errors[0].message.find("'q' is not an axis"), std::string::npos);
  EXPECT_EQ(errors[0].where.line, testing::pos_of(bad, "q: {").line);
  EXPECT_NE(errors[1].message.find("kp"), std::string::npos);
}

TEST(ConfigShaper, OverrideForAMissingAxisIsAnError) {
  const std::string y = std::string(testing::kMinimal) +
                        "feedforward:\n  shaper:\n    axes:\n      q: {freq_hz: 40}\n";
  const std::vector<Error> errors = check_config_text(y, "s.yaml");
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_NE(errors[0].message.find("'q' is not an axis"), std::string::npos);
  EXPECT_EQ(errors[0].where.line, testing::pos_of(y, "q: {").line);
}

TEST(ConfigDiff, ChangedSectionsAgreesWithEquality) {
  const MachineConfig base = default_config();
  EXPECT_TRUE(changed_sections(base, base).empty());
  MachineConfig c = base;
  c.planner.max_accel_mm_s2 = 6000;
  c.mcus[0].clock_hz = 48000000;
  EXPECT_EQ(changed_sections(base, c), (std::vector<std::string>{"planner", "mcus"}));
  // Every section the loader can change is covered: configs that differ have a changed section.
  Result<MachineConfig> full = load_config_text(full_yaml(), "full.yaml");
  Result<MachineConfig> delta = load_config_file(testing::example_path("delta_sim.yaml"));
  ASSERT_TRUE(full.ok() && delta.ok());
  for (const MachineConfig* other : {&*full, &*delta}) {
    EXPECT_FALSE(*other == base);
    EXPECT_FALSE(changed_sections(base, *other).empty());
  }
  MachineConfig only_logging = base;
  only_logging.logging.level = LogLevel::debug;
  EXPECT_EQ(changed_sections(base, only_logging), (std::vector<std::string>{"logging"}));
}

}  // namespace
}  // namespace feedloop::config
