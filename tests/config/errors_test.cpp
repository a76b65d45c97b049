// Invalid configs: every kind of problem is reported with the right file:line:column and a message
// that says what is wrong, all problems at once, and a bad config never yields a MachineConfig.
#include <gtest/gtest.h>

#include "config/config.hpp"
#include "config_fixture.hpp"

namespace feedloop::config {
namespace {

using testing::edit;
using testing::kMinimal;
using testing::Pos;
using testing::pos_of;

// The problem whose message contains `text` (an empty Error when none does).
Error find_error(const std::vector<Error>& errors, const std::string& text) {
  for (const Error& e : errors)
    if (e.message.find(text) != std::string::npos) return e;
  return Error{};
}

std::string all(const std::vector<Error>& errors) {
  std::string s;
  for (const Error& e : errors) s += e.to_string() + "\n";
  return s;
}

// Checks that loading `yaml` fails, with a problem containing `text` at `at`.
void expect_error(const std::string& yaml, const std::string& text, Pos at) {
  const std::vector<Error> errors = check_config_text(yaml, "printer.yaml");
  ASSERT_FALSE(errors.empty()) << "no problem found in:\n" << yaml;
  const Error e = find_error(errors, text);
  ASSERT_FALSE(e.message.empty()) << "no problem mentions '" << text << "'; got:\n" << all(errors);
  EXPECT_EQ(e.where.source, "printer.yaml");
  EXPECT_EQ(e.where.line, at.line) << e.to_string();
  EXPECT_EQ(e.where.column, at.column) << e.to_string();
  // And the full loader refuses the file.
  EXPECT_FALSE(load_config_text(yaml, "printer.yaml").ok());
}

TEST(ConfigErrors, MinimalFixtureIsValid) {
  EXPECT_EQ(all(check_config_text(kMinimal, "printer.yaml")), "");
}

TEST(ConfigErrors, UnknownKeyWithSuggestion) {
  const std::string y = edit(kMinimal, "steps_per_mm: 400", "steps_per_mn: 400");
  expect_error(y, "unknown key 'steps_per_mn' in axes.z (did you mean 'steps_per_mm'?)",
               pos_of(y, "steps_per_mn"));
}

TEST(ConfigErrors, UnknownTopLevelSectionWithSuggestion) {
  const std::string y = std::string(kMinimal) + "planer:\n  max_accel_mm_s2: 3000\n";
  expect_error(y, "unknown key 'planer' in the config (did you mean 'planner'?)",
               pos_of(y, "planer"));
}

TEST(ConfigErrors, KeyInTheWrongSectionNamesItsHome) {
  const std::string y = std::string(kMinimal) + "servo:\n  junction_deviation_mm: 0.02\n";
  expect_error(y, "unknown key 'junction_deviation_mm' in servo (it belongs in planner)",
               pos_of(y, "junction_deviation_mm"));
}

TEST(ConfigErrors, WrongTypeScalar) {
  const std::string y = edit(kMinimal, "max_velocity_mm_s: 10", "max_velocity_mm_s: fast");
  expect_error(y, "axes.z.max_velocity_mm_s must be a number, got 'fast'", pos_of(y, "fast"));
}

TEST(ConfigErrors, WrongTypeMappingForNumber) {
  const std::string y = edit(kMinimal, "steps_per_mm: 96", "steps_per_mm: [96]");
  expect_error(y, "axes.e.steps_per_mm must be a number, got a list", pos_of(y, "[96]"));
}

TEST(ConfigErrors, SectionThatIsNotAMapping) {
  const std::string y = std::string(kMinimal) + "planner: 5\n";
  expect_error(y, "planner must be a mapping of keys to values, got '5'", pos_of(y, "planner: 5", 9));
}

// A long value is quoted in part (a whole non-YAML file reads as one scalar), never cut inside a
// UTF-8 character.
TEST(ConfigErrors, ALongValueIsQuotedInPart) {
  const std::string value =
      std::string(59, 'a') + "\xc3\xa9" + std::string(200, 'b');  // 'e' acute at 59-60
  const std::string y = std::string(kMinimal) + "planner: " + value + "\n";
  expect_error(y,
               "planner must be a mapping of keys to values, got '" + std::string(59, 'a') +
                   "...' (261 bytes)",
               pos_of(y, "planner: a", 9));
}

TEST(ConfigErrors, MissingRequiredKey) {
  const std::string y = edit(kMinimal, "    max_accel_mm_s2: 100\n", "");
  // Reported at the start of the axis mapping that lacks it (its first key).
  expect_error(y, "missing required key 'axes.z.max_accel_mm_s2'",
               pos_of(y, "steps_per_mm: 400"));
}

TEST(ConfigErrors, MissingKinematics) {
  const std::string y = edit(kMinimal, "kinematics: cartesian\n", "");
  expect_error(y, "missing required key 'kinematics'", Pos{1, 1});
}

TEST(ConfigErrors, NegativeMass) {
  const std::string y = edit(kMinimal, "m2_kg: 0.45", "m2_kg: -0.45");
  expect_error(y, "model.gantry.x.m2_kg must be in [0.001, 1000] kg, got -0.45",
               pos_of(y, "-0.45"));
}

// A belt stiffness no machine has (1e300 N/m was accepted and the feedforward designed on it).
TEST(ConfigErrors, ImplausibleStiffness) {
  const std::string y = edit(kMinimal, "k2_n_per_m: 110e3", "k2_n_per_m: 1e300");
  expect_error(y, "model.gantry.x.k2_n_per_m must be in [100, 1e+10] N/m, got 1e+300",
               pos_of(y, "1e300"));
}

// A field lag needs the load angle's damping: with c1 0 the feedforward's lead-lag would have its
// pole at z = -1 and ring at half the servo rate.
TEST(ConfigErrors, AFieldLagWithoutTheMotorsDamping) {
  const std::string y = edit(kMinimal, "      c1_ns_per_m: 2100\n",
                             "      c1_ns_per_m: 0\n      field_lag_ms: 0.2\n");
  expect_error(y, "field_lag_ms needs the motor's damping", pos_of(y, "field_lag_ms"));
  EXPECT_EQ(all(check_config_text(edit(kMinimal, "      c1_ns_per_m: 2100\n",
                                       "      c1_ns_per_m: 2100\n      field_lag_ms: 0.2\n"),
                                  "printer.yaml")),
            "");
}

TEST(ConfigErrors, ZeroStepsPerMm) {
  const std::string y = edit(kMinimal, "steps_per_mm: 80", "steps_per_mm: 0");
  expect_error(y, "axes.x.steps_per_mm must be > 0 1/mm, got 0", pos_of(y, "0\n    encoder", 0));
}

TEST(ConfigErrors, TravelMinNotBelowMax) {
  const std::string y = edit(kMinimal, "max_mm: 180", "max_mm: -5");
  expect_error(y, "axes.z: travel min_mm (0) must be less than max_mm (-5)", pos_of(y, "max_mm: -5"));
}

TEST(ConfigErrors, UnitOfTheWrongDimension) {
  const std::string y = edit(kMinimal, "max_accel_mm_s2: 100", "max_accel_mm_s2: 300 mm/s");
  expect_error(y, "axes.z.max_accel_mm_s2: '300 mm/s' is a velocity, but max_accel_mm_s2 is an "
                  "acceleration (mm/s^2)",
               pos_of(y, "300 mm/s"));
}

TEST(ConfigErrors, UnitOnADimensionlessKey) {
  const std::string y = std::string(kMinimal) + "control:\n  kp: 0.5 mm\n";
  expect_error(y, "control.kp: '0.5 mm' is a length, but kp is a dimensionless number",
               pos_of(y, "0.5 mm"));
}

TEST(ConfigErrors, UnknownUnit) {
  const std::string y = edit(kMinimal, "resolution_um: 0.49", "resolution_um: 0.49 furlongs");
  expect_error(y, "axes.x.encoder.resolution_um: unknown unit 'furlongs'", pos_of(y, "0.49 furlongs"));
}

// fuzz/corpus/config/regress_name_not_utf8: a name with bytes that are not UTF-8 was accepted,
// reached the status JSON and M115 as is, and to_yaml() wrote it back as U+FFFD.
TEST(ConfigErrors, TextThatIsNotUtf8IsRefusedAtItsFirstBadByte) {
  const std::string y = edit(kMinimal, "kinematics: cartesian",
                             "kinematics: cartesian\nname: \"printer \xD2\xD2 one\"");
  const std::vector<Error> errors = check_config_text(y, "printer.yaml");
  ASSERT_EQ(errors.size(), 1u) << all(errors);
  expect_error(y, "not valid UTF-8 (byte 0xD2)", pos_of(y, "\xD2"));
  // Valid UTF-8 is fine, and survives the round trip.
  const std::string ok =
      edit(kMinimal, "kinematics: cartesian", "kinematics: cartesian\nname: \"Drucker \u00fc\"");
  const auto cfg = load_config_text(ok, "printer.yaml");
  ASSERT_TRUE(cfg.ok()) << cfg.error().to_string();
  EXPECT_EQ(cfg->name, "Drucker \u00fc");
  EXPECT_EQ(load_config_text(to_yaml(*cfg), "again.yaml")->name, "Drucker \u00fc");
}

TEST(ConfigErrors, YamlSyntaxErrorHasLineAndColumn) {
  const std::string y = edit(kMinimal, "axes: [x, y]", "axes: [x, y");
  const std::vector<Error> errors = check_config_text(y, "printer.yaml");
  ASSERT_EQ(errors.size(), 1u) << all(errors);
  EXPECT_NE(errors[0].message.find("YAML syntax error"), std::string::npos);
  // yaml-cpp notices the unclosed flow list on the next line.
  EXPECT_EQ(errors[0].where.line, pos_of(y, "axes: [x, y").line + 1);
  EXPECT_GT(errors[0].where.column, 0);
}

TEST(ConfigErrors, TabIndentationIsASyntaxError) {
  const std::string y = edit(kMinimal, "  z:\n    steps_per_mm: 400", "  z:\n\tsteps_per_mm: 400");
  const std::vector<Error> errors = check_config_text(y, "printer.yaml");
  ASSERT_EQ(errors.size(), 1u) << all(errors);
  EXPECT_NE(errors[0].message.find("YAML syntax error"), std::string::npos) << errors[0].message;
  EXPECT_EQ(errors[0].where.line, pos_of(y, "\tsteps").line) << errors[0].to_string();
}

TEST(ConfigErrors, DuplicateAxis) {
  const std::string y = edit(kMinimal, "  e:\n", "  x:\n    steps_per_mm: 1\n  e:\n");
  const Pos second = pos_of(y, "  x:\n    steps_per_mm: 1", 2);
  expect_error(y, "duplicate key 'x' in axes (first defined at line 3)", second);
}

TEST(ConfigErrors, AxisWithoutMcu) {
  const std::string y = edit(kMinimal, "    axes: [z]\n", "    axes: [e]\n");
  // z is now driven by nobody, e by two MCUs.
  expect_error(y, "axis 'z' is not driven by any mcu", pos_of(y, "  z:", 2));
  const std::string second_e = "axes: [e]\n    transport: mock\n  - name: mcu_e\n    axes: [e]";
  expect_error(y, "axis 'e' is already driven by mcu 'mcu_z'",
               pos_of(y, second_e, second_e.size() - 2));
}

TEST(ConfigErrors, McuNamesUnknownAxisWithSuggestion) {
  const std::string y = edit(kMinimal, "axes: [x, y]", "axes: [X, y]");
  expect_error(y, "mcus[0].axes: 'X' is not an axis in axes (did you mean 'x'?)",
               pos_of(y, "X, y"));
}

TEST(ConfigErrors, KinematicsNeedsItsAxes) {
  std::string y = edit(kMinimal, "  y:\n    steps_per_mm: 80\n    min_mm: 0\n    max_mm: 200\n"
                                 "    max_velocity_mm_s: 300\n    max_accel_mm_s2: 3000\n", "");
  y = edit(y, "axes: [x, y]", "axes: [x]");
  expect_error(y, "kinematics cartesian needs axis 'y', missing from axes", pos_of(y, "  x:", 2));
}

TEST(ConfigErrors, AxisNameForeignToTheKinematics) {
  const std::string y = edit(kMinimal, "  e:\n", "  A:\n    steps_per_mm: 1\n  e:\n");
  expect_error(y, "axis 'A' does not exist with kinematics cartesian", pos_of(y, "  A:", 2));
}

TEST(ConfigErrors, UnknownEnumValueWithSuggestion) {
  const std::string y = edit(kMinimal, "kinematics: cartesian", "kinematics: cartesain");
  expect_error(y, "kinematics must be one of cartesian, corexy, delta, got 'cartesain' "
                  "(did you mean 'cartesian'?)",
               pos_of(y, "cartesain"));
}

TEST(ConfigErrors, AxesAreCheckedEvenWhenTheKinematicsIsBroken) {
  std::string y = edit(kMinimal, "kinematics: cartesian", "kinematics: 3");
  y = edit(y, "steps_per_mm: 400", "steps_per_mm: 0");
  const std::vector<Error> errors = check_config_text(y, "printer.yaml");
  EXPECT_EQ(errors.size(), 2u) << all(errors);
  EXPECT_EQ(find_error(errors, "axes.z.steps_per_mm must be > 0").where.line,
            pos_of(y, "steps_per_mm: 0").line);
  EXPECT_EQ(find_error(errors, "kinematics must be one of").where.line, 1);
}

TEST(ConfigErrors, DuplicateMcuName) {
  const std::string y = edit(kMinimal, "name: mcu_z", "name: mcu_xy");
  expect_error(y, "duplicate mcu name 'mcu_xy' (first at line 36)", pos_of(y, "name: mcu_xy\n    axes: [z]"));
}

TEST(ConfigErrors, SerialTransportNeedsADevice) {
  const std::string y = edit(kMinimal, "    axes: [e]\n    transport: mock\n",
                             "    axes: [e]\n    transport: serial\n    serial: {baud: 250000}\n");
  expect_error(y, "missing required key 'mcus[2].serial.device'", pos_of(y, "{baud"));
}

TEST(ConfigErrors, UsbIdsOutOfRange) {
  const std::string y = edit(kMinimal, "    axes: [e]\n    transport: mock\n",
                             "    axes: [e]\n    transport: usb\n    usb: {vid: 0x1209, pid: 0x1ffff}\n");
  expect_error(y, "mcus[2].usb.pid must be in [0, 65535], got 131071", pos_of(y, "0x1ffff"));
}

TEST(ConfigErrors, SocketModeMustBeOctal) {
  const std::string y = std::string(kMinimal) + "sockets:\n  mode: \"0968\"\n";
  expect_error(y, "sockets.mode must be octal permission bits", pos_of(y, "\"0968\""));
}

TEST(ConfigErrors, UnknownPathVariable) {
  const std::string y = std::string(kMinimal) + "recorder:\n  directory: ${HOME}/rec\n";
  expect_error(y, "recorder.directory: unknown variable ${HOME}", pos_of(y, "${HOME}"));
}

TEST(ConfigErrors, SharpCornerBandMustBeOrdered) {
  const std::string y =
      std::string(kMinimal) + "planner:\n  sharp_corner: {alpha_a_deg: 30, alpha_b_deg: 20}\n";
  expect_error(y, "alpha_a_deg (30) must be less than alpha_b_deg (20)", pos_of(y, "alpha_b_deg"));
}

TEST(ConfigErrors, PiControlNeedsAnEncoder) {
  std::string y = edit(kMinimal, "    encoder: {resolution_um: 0.49}\n", "");
  y += "control:\n  mode: pi\n";
  expect_error(y, "control.mode is pi but no axis has an encoder", pos_of(y, "control:"));
}

TEST(ConfigErrors, EffectParametersAreChecked) {
  const std::string y = std::string(kMinimal) +
                        "simulator:\n  effects:\n    backlash: {width_um: -3}\n"
                        "    extra_resonance: {freq_hz: 90}\n";
  expect_error(y, "simulator.effects.backlash.width_um must be >= 0 um, got -3", pos_of(y, "-3"));
  expect_error(y, "missing required key 'simulator.effects.extra_resonance.damping'",
               pos_of(y, "{freq_hz: 90}"));
}

TEST(ConfigErrors, StepQueueShorterThanTwoServoPeriods) {
  const std::string y = std::string(kMinimal) + "servo: {rate_hz: 200}\nstepgen:\n  queue_ahead_ms: 5\n";
  expect_error(y, "stepgen.queue_ahead_ms (5) must be at least two servo periods (10 ms at "
                  "servo.rate_hz 200)",
               pos_of(y, "stepgen:"));
}

// The device loop's MCUs hold 512 knots of r(t) per motor; at 3000 mm/s^2 they come up to 866 a
// second (knots within 0.5 um): a lead past 537 ms would overflow the queue on a tight curve.
TEST(ConfigErrors, AStepLeadLongerThanTheDeviceHoldsOfTheTrajectory) {
  const std::string base = std::string(kMinimal) + "planner: {max_accel_mm_s2: 3000}\n";
  const std::string y = base + "control:\n  mode: pi\nstepgen:\n  queue_ahead_ms: 700\n";
  expect_error(
      y,
      "stepgen.queue_ahead_ms (700) is more of r(t) than the device loop's MCUs hold: at "
      "planner.max_accel_mm_s2 3000 its knots come up to 866 a second and an MCU holds 512 "
      "per motor: at most 537 ms",
      pos_of(y, "stepgen:"));
  // The PI on the host streams no r(t); a lead within the bound is taken.
  EXPECT_TRUE(
      load_config_text(
          base + "control:\n  mode: pi\n  loop: host\nstepgen:\n  queue_ahead_ms: 700\n", "t.yaml")
          .ok());
  EXPECT_TRUE(
      load_config_text(base + "control:\n  mode: pi\nstepgen:\n  queue_ahead_ms: 500\n", "t.yaml")
          .ok());
}

// ---- delta ----

std::string delta_yaml() {
  return "kinematics: delta\n"
         "axes:\n"
         "  A: {steps_per_mm: 80, min_mm: 150, max_mm: 600, max_velocity_mm_s: 300, max_accel_mm_s2: 5000}\n"
         "  B: {steps_per_mm: 80, min_mm: 150, max_mm: 600, max_velocity_mm_s: 300, max_accel_mm_s2: 5000}\n"
         "  C: {steps_per_mm: 80, min_mm: 150, max_mm: 600, max_velocity_mm_s: 300, max_accel_mm_s2: 5000}\n"
         "delta: {radius_mm: 145, arm_length_mm: 300, nozzle_offset_mm: 20, print_radius_mm: 100, "
         "z_max_mm: 250}\n"
         "mcus:\n"
         "  - {name: m, axes: [A, B, C], transport: mock}\n";
}

TEST(ConfigErrors, DeltaFixtureIsValidAndReachable) {
  Result<MachineConfig> r = load_config_text(delta_yaml(), "delta.yaml");
  ASSERT_TRUE(r.ok()) << r.error().to_string();
  EXPECT_DOUBLE_EQ(r->delta->angle_a_deg, 0.0);  // canonical defaults
  EXPECT_DOUBLE_EQ(r->delta->angle_c_deg, 240.0);
}

TEST(ConfigErrors, DeltaArmsTooShortForThePrintDisc) {
  const std::string y = edit(delta_yaml(), "arm_length_mm: 300", "arm_length_mm: 240");
  // Far edge of a 100 mm disc is 245 mm from each tower at R = 145 mm.
  expect_error(y, "delta geometry unreachable: the edge of the print disc (print_radius_mm 100) is 245 mm "
                  "from carriage A's tower",
               pos_of(y, "delta: {"));
}

TEST(ConfigErrors, DeltaCarriageTravelTooShort) {
  const std::string y = edit(delta_yaml(), "  A: {steps_per_mm: 80, min_mm: 150, max_mm: 600",
                             "  A: {steps_per_mm: 80, min_mm: 150, max_mm: 400");
  // q = z + H_ez + sqrt(L^2 - d^2): 193 mm at the far edge at z = 0, 567 mm near the tower at
  // z = 250 mm.
  expect_error(y, "carriage A must travel 193 .. 567 mm", pos_of(y, "  A:", 2));
}

TEST(ConfigErrors, GantryModelOnADelta) {
  const std::string y = delta_yaml() + "model:\n  gantry:\n    A: {m1_kg: 1}\n";
  expect_error(y, "model.gantry is for cartesian and corexy machines", pos_of(y, "A: {m1_kg"));
}

// ---- all problems at once ----

TEST(ConfigErrors, AllProblemsReportedTogetherInFileOrder) {
  std::string y = edit(kMinimal, "steps_per_mm: 80", "steps_per_mm: -1");
  y = edit(y, "m1_kg: 0.130", "m1_kg: heavy");
  y = edit(y, "transport: mock", "transport: mok");
  const std::vector<Error> errors = check_config_text(y, "printer.yaml");
  ASSERT_EQ(errors.size(), 3u) << all(errors);
  Result<MachineConfig> r = load_config_text(y, "printer.yaml");
  ASSERT_FALSE(r.ok());
  const std::string text = r.error().to_string();
  // One "file:line:col: message" line per problem, in file order.
  const Pos a = pos_of(y, "-1"), b = pos_of(y, "heavy"), c = pos_of(y, "mok");
  const std::string la = "printer.yaml:" + std::to_string(a.line) + ":" + std::to_string(a.column) + ": ";
  const std::string lb = "printer.yaml:" + std::to_string(b.line) + ":" + std::to_string(b.column) + ": ";
  const std::string lc = "printer.yaml:" + std::to_string(c.line) + ":" + std::to_string(c.column) + ": ";
  EXPECT_EQ(text.rfind(la, 0), 0u) << text;
  EXPECT_NE(text.find("\n" + lb), std::string::npos) << text;
  EXPECT_NE(text.find("\n" + lc), std::string::npos) << text;
  EXPECT_LT(text.find(lb), text.find(lc));
  EXPECT_NE(text.find("(did you mean 'mock'?)"), std::string::npos);
  EXPECT_EQ(r.error().where.line, a.line);
}

TEST(ConfigErrors, EmptyAndNonMappingDocuments) {
  EXPECT_NE(find_error(check_config_text("", "e.yaml"), "the config is empty").message, "");
  EXPECT_NE(find_error(check_config_text("- a\n- b\n", "e.yaml"), "must be a mapping").message, "");
}

// Plausibility: values that are typing errors, and the step rate that steps/mm and speed imply
// (steps_per_mm: 1e12 used to be accepted; the daemon's memory then grew without bound).
TEST(ConfigErrors, ImplausibleStepsPerMmIsAnError) {
  const std::string y = edit(kMinimal, "steps_per_mm: 400", "steps_per_mm: 1e12");
  expect_error(y, "axes.z.steps_per_mm", pos_of(y, "1e12"));
  const std::vector<Error> errors = check_config_text(y, "printer.yaml");
  EXPECT_NE(find_error(errors, "axes.z.steps_per_mm").message.find("1e+06"), std::string::npos) << all(errors);
}

TEST(ConfigErrors, StepRateImpliedByStepsPerMmAndSpeedIsBounded) {
  // 20000 steps/mm x 300 mm/s = 6e6 steps/s.
  const std::string y = edit(kMinimal, "    steps_per_mm: 80\n    encoder", "    steps_per_mm: 20000\n    encoder");
  expect_error(y, "axes.x: steps_per_mm 20000 x max_velocity_mm_s 300 = 6e+06 steps/s",
               pos_of(y, "steps_per_mm: 20000"));
  // The same steps/mm at a speed the pipeline follows is fine.
  const std::string ok = edit(y, "max_velocity_mm_s: 300\n    max_accel_mm_s2: 3000\n  y:",
                              "max_velocity_mm_s: 150\n    max_accel_mm_s2: 3000\n  y:");
  EXPECT_TRUE(check_config_text(ok, "printer.yaml").empty()) << all(check_config_text(ok, "printer.yaml"));
}

TEST(ConfigErrors, ImplausibleRatesAreErrors) {
  const std::string y = edit(kMinimal, "max_velocity_mm_s: 10", "max_velocity_mm_s: 50000");
  expect_error(y, "axes.z.max_velocity_mm_s", pos_of(y, "50000"));
  const std::string a = edit(kMinimal, "max_accel_mm_s2: 100", "max_accel_mm_s2: 1e9");
  expect_error(a, "axes.z.max_accel_mm_s2", pos_of(a, "1e9"));
}

// axes.<name>.homing (docs/homing.md): Klipper's defaults, and each implausible value reported at
// its key.
namespace homing {
const std::string kX = "    max_accel_mm_s2: 3000\n  y:";

TEST(ConfigHoming, DefaultsAreKlippers) {
  const std::string y = edit(kMinimal, kX, "    max_accel_mm_s2: 3000\n    homing: {}\n  y:");
  auto cfg = load_config_text(y, "printer.yaml");
  ASSERT_TRUE(cfg.ok()) << cfg.error().to_string();
  const AxisConfig* x = cfg->axis("x");
  ASSERT_TRUE(x && x->homing);
  EXPECT_EQ(x->homing->direction, EndstopSide::min);
  EXPECT_EQ(x->homing->position_endstop_mm, 0.0);       // min_mm
  EXPECT_EQ(x->homing->homing_speed_mm_s, 5.0);         // Klipper: homing_speed 5
  EXPECT_EQ(x->homing->second_homing_speed_mm_s, 2.5);  // homing_speed / 2
  EXPECT_EQ(x->homing->retract_dist_mm, 5.0);           // homing_retract_dist 5
  EXPECT_EQ(x->homing->max_travel_mm, 300.0);           // 1.5 x (200 - 0)
  EXPECT_FALSE(cfg->axis("y")->homing.has_value());     // no section: no endstop
}

TEST(ConfigHoming, EndstopAtMaxInfersTheDirection) {
  const std::string y =
      edit(kMinimal, kX, "    max_accel_mm_s2: 3000\n    homing: {position_endstop_mm: 200}\n  y:");
  auto cfg = load_config_text(y, "printer.yaml");
  ASSERT_TRUE(cfg.ok()) << cfg.error().to_string();
  EXPECT_EQ(cfg->axis("x")->homing->direction, EndstopSide::max);
  // And the default position follows an explicit direction.
  const std::string y2 =
      edit(kMinimal, kX, "    max_accel_mm_s2: 3000\n    homing: {direction: max}\n  y:");
  auto cfg2 = load_config_text(y2, "printer.yaml");
  ASSERT_TRUE(cfg2.ok());
  EXPECT_EQ(cfg2->axis("x")->homing->position_endstop_mm, 200.0);
}

TEST(ConfigHoming, EndstopOutsideTheTravel) {
  const std::string y =
      edit(kMinimal, kX, "    max_accel_mm_s2: 3000\n    homing: {position_endstop_mm: 250}\n  y:");
  expect_error(y, "axes.x.homing.position_endstop_mm 250 mm must lie within the travel 0 .. 200 mm",
               pos_of(y, "position_endstop_mm: 250"));
}

TEST(ConfigHoming, SecondTouchFasterThanTheFirst) {
  const std::string y = edit(kMinimal, kX,
                             "    max_accel_mm_s2: 3000\n    homing:\n      homing_speed_mm_s: 20\n"
                             "      second_homing_speed_mm_s: 40\n  y:");
  expect_error(y, "axes.x.homing.second_homing_speed_mm_s 40 mm/s is above homing_speed_mm_s 20",
               pos_of(y, "second_homing_speed_mm_s"));
}

TEST(ConfigHoming, EncoderIndexHomingNeedsTheEncodersIndexMarks) {
  const std::string y =
      edit(kMinimal, kX, "    max_accel_mm_s2: 3000\n    homing: {index: true}\n  y:");
  expect_error(y,
               "axes.x.homing.index: encoder-index homing needs axes.x.encoder.index_period_mm "
               "(the encoder's index marks)",
               pos_of(y, "index: true"));
}

TEST(ConfigHoming, OvershootBeyondTheRetract) {
  const std::string y =
      edit(kMinimal, kX,
           "    max_accel_mm_s2: 3000\n    homing:\n      homing_speed_mm_s: 300\n"
           "      retract_dist_mm: 0.05\n  y:");
  expect_error(y,
               "overshoots the trip point by 0.06 mm before the MCU confirms it, more than "
               "retract_dist_mm 0.05",
               pos_of(y, "homing_speed_mm_s: 300"));
}

TEST(ConfigHoming, BadDirectionAndSpeedAboveTheAxisLimit) {
  const std::string y =
      edit(kMinimal, kX,
           "    max_accel_mm_s2: 3000\n    homing: {direction: up, homing_speed_mm_s: 400}\n  y:");
  expect_error(y,
               "axes.x.homing.homing_speed_mm_s 400 mm/s is above the axis's max_velocity_mm_s 300",
               pos_of(y, "homing_speed_mm_s: 400"));
  expect_error(y, "direction", pos_of(y, "up,"));
}

TEST(ConfigHoming, NotOnTheExtruder) {
  const std::string y =
      edit(kMinimal, "    steps_per_mm: 96\n", "    steps_per_mm: 96\n    homing: {}\n");
  expect_error(y, "axes.e: the extruder has no endstop", pos_of(y, "homing: {}"));
}
// CoreXY (docs/homing.md "CoreXY"): the carriage's switches on x and y, both or neither, and both
// motors with the same steps/mm (they step together).
TEST(ConfigHoming, CoreXyNeedsBothSwitchesAndEqualSteps) {
  const std::string corexy = edit(kMinimal, "kinematics: cartesian", "kinematics: corexy");
  const std::string both =
      edit(edit(corexy, kX, "    max_accel_mm_s2: 3000\n    homing: {}\n  y:"),
           "    max_accel_mm_s2: 3000\n  z:", "    max_accel_mm_s2: 3000\n    homing: {}\n  z:");
  auto cfg = load_config_text(both, "printer.yaml");
  ASSERT_TRUE(cfg.ok()) << (cfg.ok() ? "" : cfg.error().message);
  EXPECT_TRUE(cfg->axis("x")->homing && cfg->axis("y")->homing);
  const std::string only_x = edit(corexy, kX, "    max_accel_mm_s2: 3000\n    homing: {}\n  y:");
  expect_error(only_x,
               "axes.x.homing: a corexy carriage homes through both motors: give x and y a homing "
               "section each (or neither)",
               pos_of(only_x, "x:"));
  const std::string uneven = edit(both, "    steps_per_mm: 80\n    min_mm", "    steps_per_mm: 81\n    min_mm");
  expect_error(uneven,
               "x and y need the same steps_per_mm (80 and 81)", pos_of(uneven, "x:"));
}
}  // namespace homing

}  // namespace
}  // namespace feedloop::config
