// Valid configs: the examples load with the papers' values, the embedded default is
// cartesian_sim.yaml, defaults fill what a file leaves out, units convert, to_yaml round-trips.
#include <gtest/gtest.h>

#include <cmath>

#include "config/calibration.hpp"
#include "config/config.hpp"
#include "config_fixture.hpp"

namespace feedloop::config {
namespace {

using testing::edit;
using testing::example_path;
using testing::kMinimal;

MachineConfig must_load(const std::string& yaml) {
  Result<MachineConfig> r = load_config_text(yaml, "test.yaml");
  EXPECT_TRUE(r.ok()) << (r.ok() ? "" : r.error().to_string());
  return r.ok() ? r.value() : MachineConfig{};
}

const GantryModelConfig* gantry(const MachineConfig& c, const std::string& axis) {
  for (const GantryModelConfig& g : c.model.gantry)
    if (g.axis == axis) return &g;
  return nullptr;
}

TEST(ConfigExamples, CartesianSimHasTheThesisGantry) {
  Result<MachineConfig> r = load_config_file(example_path("cartesian_sim.yaml"));
  ASSERT_TRUE(r.ok()) << r.error().to_string();
  const MachineConfig& c = *r;
  EXPECT_EQ(c.kinematics, Kinematics::cartesian);
  ASSERT_EQ(c.axes.size(), 4u);
  // 3200 microsteps per turn / (2 pi 5.40 mm)
  EXPECT_NEAR(c.axis("x")->steps_per_mm, 3200.0 / (2.0 * M_PI * 5.40), 1e-3);
  ASSERT_TRUE(c.axis("x")->encoder);
  EXPECT_DOUBLE_EQ(c.axis("x")->encoder->resolution_um, 0.49);
  EXPECT_FALSE(c.axis("z")->encoder);
  EXPECT_TRUE(std::isinf(c.axis("e")->min_mm));
  const GantryModelConfig* x = gantry(c, "x");
  const GantryModelConfig* y = gantry(c, "y");
  ASSERT_TRUE(x && y);
  EXPECT_DOUBLE_EQ(x->k1_n_per_m, 355e3);  // Table 4
  EXPECT_DOUBLE_EQ(y->k2_n_per_m, 19.7e3);
  EXPECT_DOUBLE_EQ(y->c2_ns_per_m, 71.5);
  EXPECT_DOUBLE_EQ(y->m2_kg, 1.07);
  // m1 = J / r^2 (Eq. 14) with Table 2's J and r reproduces Table 3's 0.130 kg.
  const double r_m = x->stepper.pulley_radius_mm * 1e-3;
  EXPECT_NEAR(x->stepper.rotor_inertia_kg_m2 / (r_m * r_m), x->m1_kg, 0.001);
  // psi_3 = c1/m1 + c2/m2 (Eq. 16) vs the fitted 16380.8 of Eq. 18 for X: within 1 %.
  EXPECT_NEAR(x->c1_ns_per_m / x->m1_kg + x->c2_ns_per_m / x->m2_kg, 16380.8, 0.01 * 16380.8);
  EXPECT_EQ(c.control.mode, ControlMode::pi);
  EXPECT_DOUBLE_EQ(c.control.kp, 0.5);
  EXPECT_DOUBLE_EQ(c.control.ki_per_s, 20.0);
  EXPECT_DOUBLE_EQ(c.servo.rate_hz, 1000.0);
  ASSERT_EQ(c.mcus.size(), 4u);
  EXPECT_TRUE(c.uses_simulator());
  EXPECT_EQ(c.sockets.mode, 0660u);
}

TEST(ConfigExamples, DeltaSimHasCanonicalGeometryAndTableOne) {
  Result<MachineConfig> r = load_config_file(example_path("delta_sim.yaml"));
  ASSERT_TRUE(r.ok()) << r.error().to_string();
  const MachineConfig& c = *r;
  EXPECT_EQ(c.kinematics, Kinematics::delta);
  ASSERT_TRUE(c.delta);
  EXPECT_DOUBLE_EQ(c.delta->radius_mm, 145.0);
  EXPECT_DOUBLE_EQ(c.delta->arm_length_mm, 300.0);
  EXPECT_DOUBLE_EQ(c.delta->nozzle_offset_mm, 20.0);
  EXPECT_DOUBLE_EQ(c.delta->angle_b_deg, 120.0);
  EXPECT_DOUBLE_EQ(c.delta->angle_c_deg, 240.0);
  ASSERT_TRUE(c.model.delta_lpv);
  const DeltaLpvConfig& p = *c.model.delta_lpv;
  EXPECT_DOUBLE_EQ(p.d1_per_s, -212.1);
  EXPECT_DOUBLE_EQ(p.delta_y_mm, -16.52);
  EXPECT_EQ(p.force_transform, ForceTransform::virtual_work);  // what the identification supports
  // DESIGN.md: m = m_c + m_f/2 = 0.195 kg and k = 1.21e5 N/m give omega_n = 787.7 rad/s.
  EXPECT_NEAR(std::sqrt(p.k_n_per_m / (p.m_c_kg + p.m_f_kg / 2)), 787.7, 0.1);
  // The electrical mode: sqrt(d0) = 378 rad/s = 60.2 Hz.
  EXPECT_NEAR(std::sqrt(p.d0_per_s2) / (2 * M_PI), 60.2, 0.05);
  EXPECT_EQ(c.feedforward.type, FeedforwardType::lpv);
  EXPECT_NE(c.axis("A"), nullptr);
  EXPECT_EQ(c.axis("x"), nullptr);
}

TEST(ConfigExamples, CartesianUsbHasOneUsbMcuPerAxis) {
  Result<MachineConfig> r = load_config_file(example_path("cartesian_usb.yaml"));
  ASSERT_TRUE(r.ok()) << r.error().to_string();
  ASSERT_EQ(r->mcus.size(), 4u);
  for (const McuConfig& m : r->mcus) {
    EXPECT_EQ(m.transport, TransportType::usb);
    EXPECT_EQ(m.usb.vid, 0x1209);
    EXPECT_EQ(m.usb.pid, 0xf10e);
    EXPECT_EQ(m.axes.size(), 1u);
  }
  EXPECT_EQ(r->mcus[1].usb.serial, "FL-Y-0001");
  EXPECT_FALSE(r->uses_simulator());
  EXPECT_EQ(r->servo.cpu, 1);
}

TEST(ConfigEmbeddedDefault, IsCartesianSimYaml) {
  EXPECT_EQ(std::string(default_config_yaml()),
            testing::read_text(example_path("cartesian_sim.yaml")));
  Result<MachineConfig> file = load_config_file(example_path("cartesian_sim.yaml"));
  ASSERT_TRUE(file.ok());
  EXPECT_TRUE(default_config() == *file);
  EXPECT_EQ(default_config().axes.size(), 4u);
}

TEST(ConfigRoundTrip, ToYamlReloadsEqual) {
  for (const char* name : {"cartesian_sim.yaml", "delta_sim.yaml", "cartesian_usb.yaml"}) {
    Result<MachineConfig> a = load_config_file(example_path(name));
    ASSERT_TRUE(a.ok()) << name;
    const std::string text = to_yaml(*a);
    Result<MachineConfig> b = load_config_text(text, std::string("roundtrip of ") + name);
    ASSERT_TRUE(b.ok()) << b.error().to_string() << "\n" << text;
    EXPECT_TRUE(*a == *b) << name;
    EXPECT_EQ(to_yaml(*b), text) << name;  // a fixed point
  }
}

TEST(ConfigRoundTrip, AllEffectsAndSerialTransport) {
  std::string y = kMinimal;
  y += "simulator:\n"
       "  seed: 42\n"
       "  encoder_noise_um: 0.3\n"
       "  effects:\n"
       "    coulomb_friction: {force_n: 1.5}\n"
       "    backlash: {width_um: 25, axes: [x]}\n"
       "    periodic_position: {period_mm: 33.9, amplitude_um: 25, axes: [x, y]}\n"
       "    direction_dependent_stiffness: {ratio: 1.4}\n"
       "    extra_resonance: {freq_hz: 95, damping: 0.03}\n"
       "    time_delay: {delay_ms: 1.5}\n"
       "    scale_error: {scale: 1.003, axes: [y]}\n";
  y = edit(y, "  - name: mcu_e\n    axes: [e]\n    transport: mock\n",
           "  - name: mcu_e\n    axes: [e]\n    transport: serial\n"
           "    serial: {device: /dev/ttyACM0, baud: 115200}\n");
  const MachineConfig a = must_load(y);
  ASSERT_TRUE(a.simulator.effects.periodic_position);
  EXPECT_DOUBLE_EQ(a.simulator.effects.periodic_position->period_mm, 33.9);
  EXPECT_EQ(a.simulator.effects.periodic_position->axes, (std::vector<std::string>{"x", "y"}));
  EXPECT_DOUBLE_EQ(a.simulator.effects.scale_error->scale, 1.003);
  EXPECT_TRUE(a.simulator.effects.coulomb_friction->axes.empty());  // every axis
  EXPECT_TRUE(applies_to(*a.simulator.effects.coulomb_friction, "z"));
  EXPECT_TRUE(applies_to(*a.simulator.effects.backlash, "x"));
  EXPECT_FALSE(applies_to(*a.simulator.effects.backlash, "y"));
  ASSERT_NE(a.model.gantry_for("x"), nullptr);
  EXPECT_DOUBLE_EQ(a.model.gantry_for("x")->k2_n_per_m, 110e3);
  EXPECT_EQ(a.model.gantry_for("y"), nullptr);
  EXPECT_EQ(a.simulator.seed, 42u);
  EXPECT_EQ(a.mcus[2].serial.device, "/dev/ttyACM0");
  EXPECT_EQ(a.mcus[2].serial.baud, 115200);
  const MachineConfig b = must_load(to_yaml(a));
  EXPECT_TRUE(a == b);
}

TEST(ConfigDefaults, FillEverythingAFileLeavesOut) {
  const MachineConfig c = must_load(kMinimal);
  const MachineConfig d;  // struct defaults
  EXPECT_DOUBLE_EQ(c.planner.junction_deviation_mm, 0.013);
  EXPECT_DOUBLE_EQ(c.planner.square_corner_velocity_mm_s, 5.0);
  EXPECT_DOUBLE_EQ(c.planner.min_cruise_ratio, 0.5);
  EXPECT_DOUBLE_EQ(c.planner.sharp_corner.alpha_b_deg, 20.0);
  EXPECT_DOUBLE_EQ(c.stepgen.max_step_error_us, 5.0);
  EXPECT_EQ(c.mcus[0].clock_hz, c.stepgen.mcu_clock_hz);
  EXPECT_TRUE(c.planner == d.planner);
  EXPECT_TRUE(c.servo == d.servo);
  EXPECT_TRUE(c.control == d.control);
  EXPECT_TRUE(c.simulator == d.simulator);
  EXPECT_TRUE(c.sockets == d.sockets);
  EXPECT_FALSE(c.simulator.effects.backlash);
  // The gantry stepper section defaults to Table 2's motor.
  ASSERT_EQ(c.model.gantry.size(), 1u);
  EXPECT_DOUBLE_EQ(c.model.gantry[0].stepper.holding_torque_nm, 0.285);
  EXPECT_EQ(c.model.gantry[0].stepper.rotor_teeth, 50);
}

TEST(ConfigUnits, WrittenUnitsConvertToTheKeysUnit) {
  std::string y = edit(kMinimal, "max_accel_mm_s2: 3000\n  y:", "max_accel_mm_s2: 3.5 m/s^2\n  y:");
  y = edit(y, "resolution_um: 0.49", "resolution_um: 0.00049 mm");
  y = edit(y, "k1_n_per_m: 355e3", "k1_n_per_m: 355 kN/m");
  y += "feedforward:\n  shaper: {freq_hz: 730 rad/s}\nservo: {rate_hz: 4 kHz}\n"
       "simulator: {sample_delay_us: 0.25 ms}\n";
  const MachineConfig c = must_load(y);
  EXPECT_DOUBLE_EQ(c.axis("x")->max_accel_mm_s2, 3500.0);
  EXPECT_NEAR(c.axis("x")->encoder->resolution_um, 0.49, 1e-12);
  EXPECT_DOUBLE_EQ(c.model.gantry[0].k1_n_per_m, 355e3);
  EXPECT_NEAR(c.feedforward.shaper.freq_hz, 730.0 / (2 * M_PI), 1e-9);
  EXPECT_DOUBLE_EQ(c.servo.rate_hz, 4000.0);
  EXPECT_DOUBLE_EQ(c.simulator.sample_delay_us, 250.0);
}

TEST(ConfigPaths, ExpandRuntimeAndStateDirs) {
  const PathVars v{"/run/feedloop", "/var/lib/feedloop"};
  Result<std::string> a = expand_path("${RUNTIME_DIR}/feedloop.sock", v);
  ASSERT_TRUE(a.ok());
  EXPECT_EQ(*a, "/run/feedloop/feedloop.sock");
  EXPECT_EQ(*expand_path("${STATE_DIR}/rec", v), "/var/lib/feedloop/rec");
  EXPECT_EQ(*expand_path("plain/path", v), "plain/path");
  EXPECT_FALSE(expand_path("${HOME}/x", v).ok());
  EXPECT_FALSE(expand_path("${RUNTIME_DIR/x", v).ok());
  const PathVars env = path_vars_from_environment();
  EXPECT_FALSE(env.runtime_dir.empty());
  EXPECT_FALSE(env.state_dir.empty());
}

TEST(ConfigFiles, MissingFileIsAnErrorNamingThePath) {
  Result<MachineConfig> r = load_config_file("no/such/dir/printer.yaml");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().where.source, "no/such/dir/printer.yaml");
  EXPECT_NE(r.error().to_string().find("cannot read config file"), std::string::npos);
}

// A path that never ends (/dev/zero: it was read until memory ran out) or a file far beyond any
// printer's YAML is refused after 16 MiB, for the config and the calibration overlay alike.
TEST(ConfigFiles, AFileThatIsNoConfigIsRefusedAfterABoundedRead) {
  Result<MachineConfig> r = load_config_file("/dev/zero");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().where.source, "/dev/zero");
  EXPECT_NE(r.error().message.find("larger than 16 MiB"), std::string::npos) << r.error().message;
  auto c = apply_calibration_file(default_config(), "/dev/zero");
  ASSERT_FALSE(c.ok());
  EXPECT_NE(c.error().message.find("calibration file is larger than 16 MiB"), std::string::npos)
      << c.error().message;
}

}  // namespace
}  // namespace feedloop::config

namespace feedloop::config {
namespace {

TEST(ConfigKinematics, CorexyUsesTheCartesianAxisNames) {
  const MachineConfig c = must_load(testing::edit(testing::kMinimal, "kinematics: cartesian",
                                                  "kinematics: corexy"));
  EXPECT_EQ(c.kinematics, Kinematics::corexy);
  EXPECT_NE(c.axis("y"), nullptr);
  EXPECT_FALSE(c.delta);
}

TEST(ConfigIntegers, AcceptExponentsUnitsAndHex) {
  std::string y = std::string(testing::kMinimal) + "stepgen: {mcu_clock_hz: 48 MHz}\n";
  y = testing::edit(y, "  - name: mcu_z\n    axes: [z]\n    transport: mock\n",
                    "  - name: mcu_z\n    axes: [z]\n    transport: usb\n"
                    "    usb: {vid: 0x1d50, pid: 24843}\n    clock_hz: 168e6\n");
  const MachineConfig c = must_load(y);
  EXPECT_EQ(c.stepgen.mcu_clock_hz, 48000000);
  EXPECT_EQ(c.mcus[0].clock_hz, 48000000);   // inherits stepgen's
  EXPECT_EQ(c.mcus[1].clock_hz, 168000000);  // its own
  EXPECT_EQ(c.mcus[1].usb.vid, 0x1d50);
  EXPECT_EQ(c.mcus[1].usb.pid, 24843);
  EXPECT_FALSE(load_config_text(testing::edit(y, "168e6", "168.5"), "t.yaml").ok());
}

}  // namespace
}  // namespace feedloop::config

namespace feedloop::config {
namespace {

// Thesis Eq. 16 coefficients from the config's Table 3-4 parameters against the fitted transfer
// functions of Eq. 18: a typo in the example's model values shows up here.
TEST(ConfigExamples, GantryParametersReproduceTheFittedTransferFunctions) {
  Result<MachineConfig> r = load_config_file(testing::example_path("cartesian_sim.yaml"));
  ASSERT_TRUE(r.ok());
  struct Fit {
    const char* axis;
    double psi3, psi2, psi1, psi0;
  };
  const Fit fits[] = {{"x", 16380.8, 7.82543e6, 4.82342e9, 6.65380e11},
                      {"y", 3220.54, 3.38821e6, 2.70238e8, 5.56597e10}};
  for (const Fit& f : fits) {
    const GantryModelConfig* g = gantry(*r, f.axis);
    ASSERT_NE(g, nullptr) << f.axis;
    const double m1 = g->m1_kg, m2 = g->m2_kg, k1 = g->k1_n_per_m, k2 = g->k2_n_per_m;
    const double c1 = g->c1_ns_per_m, c2 = g->c2_ns_per_m, mm = m1 * m2;
    EXPECT_NEAR((c1 * m2 + c2 * m1) / mm, f.psi3, 0.01 * f.psi3) << f.axis;
    EXPECT_NEAR((c1 * c2 + k1 * m2 + k2 * m1 + k2 * m2) / mm, f.psi2, 0.01 * f.psi2) << f.axis;
    EXPECT_NEAR((c1 * k2 + c2 * k1 + c2 * k2) / mm, f.psi1, 0.01 * f.psi1) << f.axis;
    EXPECT_NEAR(k1 * k2 / mm, f.psi0, 0.01 * f.psi0) << f.axis;
  }
}

}  // namespace
}  // namespace feedloop::config
