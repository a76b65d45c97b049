// The DC-servo machine type in the config: the example loads, writes back to an equal config, and
// every problem with the maneuvering gains or the machine type is reported at its file:line:col.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include "config/config.hpp"
#include "engine/executor_factory.hpp"
#include "engine/maneuver_executor.hpp"

namespace feedloop::engine {
namespace {

const std::string kExample = FEEDLOOP_SOURCE_DIR "/config/examples/dc_servo_sim.yaml";

std::string example_text() {
  std::ifstream in(kExample);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// `text` with the first `from` replaced by `to` (the test fails when `from` is absent).
std::string edit(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

// "dc.yaml:LINE:COL" of the first occurrence of `what` in `text` (1-based, YAML's convention).
std::string where(const std::string& text, const std::string& what) {
  const size_t at = text.find(what);
  EXPECT_NE(at, std::string::npos) << what;
  int line = 1, col = 1;
  for (size_t i = 0; i < at; ++i) {
    if (text[i] == '\n') {
      ++line;
      col = 1;
    } else {
      ++col;
    }
  }
  return "dc.yaml:" + std::to_string(line) + ":" + std::to_string(col);
}

// A problem at `at` whose message contains `message` (and, when `only`, no other problem).
void expect_error(const std::string& text, const std::string& at, const std::string& message, bool only = true) {
  const std::vector<Error> errors = config::check_config_text(text, "dc.yaml");
  if (!only) {
    std::string all;
    for (const Error& e : errors) {
      all += e.to_string() + "\n";
      if (e.to_string().rfind(at + ": ", 0) == 0 && e.to_string().find(message) != std::string::npos) return;
    }
    ADD_FAILURE() << "expected at " << at << ": " << message << "\ngot:\n" << all;
    return;
  }
  ASSERT_EQ(errors.size(), 1u) << (errors.empty() ? "no error" : errors[0].to_string() + " ... " + errors.back().to_string());
  const std::string got = errors[0].to_string();
  EXPECT_EQ(got.rfind(at + ": ", 0), 0u) << got << "\n expected at " << at;
  EXPECT_NE(got.find(message), std::string::npos) << got;
}

TEST(DcServoConfig, ExampleLoadsRoundTripsAndBuildsTheManeuverExecutor) {
  auto cfg = config::load_config_file(kExample);
  ASSERT_TRUE(cfg.ok()) << cfg.error().to_string();
  EXPECT_EQ(cfg->drive, config::Drive::dc_servo);
  EXPECT_EQ(cfg->control.mode, config::ControlMode::maneuver);
  EXPECT_TRUE(cfg->mcus.empty());
  EXPECT_TRUE(cfg->uses_simulator());
  EXPECT_DOUBLE_EQ(cfg->control.maneuver.k_d_per_s, 1667.0);
  EXPECT_DOUBLE_EQ(cfg->control.maneuver.mu, 1e-3);
  EXPECT_EQ(cfg->control.maneuver.speed_assignment, config::ManeuverSpeed::sharp_corner_arc);
  EXPECT_DOUBLE_EQ(cfg->model.cartesian_dc.pulley_radius_mm, 10.0);
  EXPECT_DOUBLE_EQ(cfg->servo.rate_hz, 5000.0);
  auto again = config::load_config_text(config::to_yaml(*cfg), "emitted.yaml");
  ASSERT_TRUE(again.ok()) << again.error().to_string() << "\n" << config::to_yaml(*cfg);
  EXPECT_TRUE(*again == *cfg);
  auto ex = make_executor(*cfg);
  ASSERT_TRUE(ex.ok()) << ex.error().message;
  EXPECT_NE(dynamic_cast<ManeuverExecutor*>(ex.value().get()), nullptr);
  // Units on the new keys convert.
  const std::string t = edit(example_text(), "pulley_radius_mm: 10", "pulley_radius_mm: 1 cm");
  auto cm = config::load_config_text(edit(t, "k_m_nm_per_a: 1.0e-4", "k_m_nm_per_a: 0.1 mNm/A"), "dc.yaml");
  ASSERT_TRUE(cm.ok()) << cm.error().to_string();
  EXPECT_DOUBLE_EQ(cm->model.cartesian_dc.pulley_radius_mm, 10.0);
  EXPECT_DOUBLE_EQ(cm->model.cartesian_dc.k_m_nm_per_a, 1e-4);
}

TEST(DcServoConfig, BadManeuverGainsAreReportedWhereTheyAreWritten) {
  const std::string base = example_text();
  // Table II's K_d sampled at 1 kHz diverges: the config says so at k_d_per_s.
  std::string t = edit(base, "rate_hz: 5000", "rate_hz: 1000");
  expect_error(t, where(t, "k_d_per_s: 1667"), "diverges above 1.5; raise servo.rate_hz to at least 1112");
  t = edit(base, "k_d_per_s: 1667", "k_d_per_s: 8000");
  expect_error(t, where(t, "k_d_per_s: 8000"), "k_d_per_s (8000) times the servo period (1/5000 s) is 1.6");
  // The default K_d with a slow servo: reported at control.mode.
  t = edit(edit(base, "rate_hz: 5000", "rate_hz: 1000"), "    k_d_per_s: 1667                      # Table II: K_d = -A_2\n", "");
  expect_error(t, where(t, "mode: maneuver"), "k_d_per_s (1667)");
  t = edit(base, "k_p_per_s: 500", "k_p_per_s: -500");
  expect_error(t, where(t, "-500"), "k_p_per_s");
  t = edit(base, "lambda_per_s: 30", "lambda_per_s: -30");
  expect_error(t, where(t, "-30"), "lambda_per_s");
  t = edit(base, "mu: 0.001", "mu: -0.001");
  expect_error(t, where(t, "-0.001"), "mu");
  t = edit(base, "speed_assignment: sharp_corner_arc", "speed_assignment: sharp_corners");
  expect_error(t, where(t, "sharp_corners"), "did you mean 'sharp_corner'");
  t = edit(base, "arc_reach_mm: 2", "arc_reach_mm: 0.05");
  expect_error(t, where(t, "arc_reach_mm: 0.05"), "must exceed arc_a1_mm + arc_a2_mm");
  t = edit(base, "path_speed_mm_s: 100", "path_speed_mm_s: 100 mm/s^2");
  expect_error(t, where(t, "100 mm/s^2"), "acceleration");
  t = edit(base, "q2: 1", "q_2: 1");
  expect_error(t, where(t, "q_2"), "did you mean 'q2'");
}

TEST(DcServoConfig, MachineTypeAndControlModeMustMatch) {
  const std::string base = example_text();
  std::string t = edit(base, "mode: maneuver", "mode: open_loop");
  expect_error(t, where(t, "control:"), "drive: dc_servo needs control.mode: maneuver");
  t = edit(base, "kinematics: cartesian", "kinematics: corexy");
  expect_error(t, where(t, "drive: dc_servo"), "is a Cartesian printer");
  t = edit(base, "recorder:", "mcus:\n  - {name: m, axes: [x, y, z, e], transport: mock}\nrecorder:");
  expect_error(t, where(t, "mcus:"), "has no mcus");
  t = edit(base, "drive: dc_servo ", "drive: dc_motor ");
  expect_error(t, where(t, "dc_motor"), "drive must be one of stepper, dc_servo", false);  // and all that a stepper lacks
  // A stepper machine (the default config) cannot take mode maneuver or the DC-motor model.
  const std::string stepper(config::default_config_yaml());
  t = edit(stepper, "mode: pi", "mode: maneuver");
  expect_error(t, where(t, "control:"), "control.mode maneuver drives voltage-driven axes: it needs drive: dc_servo",
               false);  // and Table II's K_d at the stepper config's 1 kHz
  t = edit(stepper, "model:\n", "model:\n  cartesian_dc: {m_n_kg: 0.5}\n");
  expect_error(t, where(t, "cartesian_dc"), "model.cartesian_dc is the plant of drive: dc_servo");
}

// Seeded random edits of the example (as tests/config does for the others): loading never throws,
// every problem is located inside the text, and a config either loads or reports problems.
TEST(DcServoConfig, MutatedExampleProblemsAreAllLocated) {
  const std::string original = example_text();
  int lines = 1;
  for (char c : original) lines += c == '\n';
  std::mt19937 rng(20261122);
  static const std::string alphabet = "abcxyz_:-[]{},#'\"\t\n 0123456789.e";
  int rejected = 0, accepted = 0;
  for (int i = 0; i < 200; ++i) {
    std::string text = original;
    for (int k = 0, edits = 1 + static_cast<int>(rng() % 3); k < edits; ++k) {
      const size_t at = rng() % text.size();
      switch (rng() % 3) {
        case 0: text.erase(at, 1 + rng() % 8); break;
        case 1: text.insert(at, 1, alphabet[rng() % alphabet.size()]); break;
        default: text[at] = alphabet[rng() % alphabet.size()];
      }
    }
    std::vector<Error> errors;
    ASSERT_NO_THROW(errors = config::check_config_text(text, "m.yaml"));
    EXPECT_EQ(config::load_config_text(text, "m.yaml").ok(), errors.empty());
    (errors.empty() ? accepted : rejected)++;
    for (const Error& e : errors) {
      EXPECT_GE(e.where.line, 1) << e.to_string() << "\n--- text ---\n" << text;
      EXPECT_LE(e.where.line, lines + 20) << e.to_string();
      EXPECT_GE(e.where.column, 1) << e.to_string() << "\n--- text ---\n" << text;
    }
  }
  std::printf("mutated dc_servo_sim.yaml: %d rejected, %d accepted\n", rejected, accepted);
  EXPECT_GT(rejected, 50);
}

}  // namespace
}  // namespace feedloop::engine
