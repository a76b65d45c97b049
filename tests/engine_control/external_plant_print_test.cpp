// A print against an external plant (DESIGN.md "External plant v1") in virtual time, through the
// daemon's own pipeline (engine::run_simulated): the X and Y carriages are a plant script of the
// tests (tests/sim/plants/lag_plant.py, a belt-like second-order lag the controller's model does
// not contain), Z and E stay on the built-in simulator. The device loop closes on the plant's
// answers through the configured encoder model.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "config/config.hpp"
#include "engine/sim_run.hpp"

namespace feedloop::engine {
namespace {

const std::string kPlant = "python3 " + std::string(FEEDLOOP_SOURCE_DIR) + "/tests/sim/plants/lag_plant.py";

config::MachineConfig with_plant(const std::string& options) {
  config::MachineConfig cfg = config::default_config();
  cfg.planner.allow_moves_before_homing = true;  // this fixture never homes (docs/homing.md)
  cfg.simulator.external_plant = config::ExternalPlantConfig{kPlant + " " + options, {"x", "y"}, 500.0};
  return cfg;
}

const std::vector<std::string> kProgram = {"G90", "G1 X20 Y10 F3000", "G1 X5 Y25 F3000", "G1 X12 Y12 F1500",
                                           "G4 P300"};

TEST(ExternalPlantPrint, ThePrintRunsInLockStepAndTheLoopHoldsTheTargets) {
  SimRunOptions o;
  o.settle_s = 0.3;
  auto r = run_simulated(with_plant("--freq-hz 150 --zeta 0.6"), kProgram, o);
  ASSERT_TRUE(r.ok()) << r.error().message;
  const SimRunResult& s = r.value();
  EXPECT_EQ(s.error, "");
  EXPECT_EQ(s.rejected, 0u);
  // Not asserted: lost-step events. The device's slip detector subtracts the deflection the
  // config's (thesis) belt model predicts, which this plant does not have; at the X reversal the
  // difference passes the threshold and one false slip of a torque cycle is reported and "made
  // up" (docs/simulator.md, "External plant v1": known, the model must come from the machine's
  // data, issue 15). The loop still brings the carriage back onto the target below.
  size_t lost_step_events = 0;
  for (const ServoEvent& ev : s.events) lost_step_events += ev.kind == ServoEventKind::kLostSteps;
  ASSERT_GT(s.samples.size(), 500u);
  double max_mm = 0.0, sum_mm = 0.0;
  for (const SimRunSample& x : s.samples) {
    const double e = std::hypot(x.servo.desired_mm[0] - x.actual_mm[0], x.servo.desired_mm[1] - x.actual_mm[1]);
    max_mm = std::max(max_mm, e);
    sum_mm += e;
  }
  const double mean_mm = sum_mm / static_cast<double>(s.samples.size());
  // The plant's truth (its answers), not the encoder: at rest on the last target.
  EXPECT_NEAR(s.samples.back().actual_mm[0], 12.0, 0.02);
  EXPECT_NEAR(s.samples.back().actual_mm[1], 12.0, 0.02);
  // A 150 Hz carriage lags the planned path by a fraction of a millimetre at 50 mm/s.
  EXPECT_LT(mean_mm, 0.5);
  EXPECT_LT(max_mm, 2.0);
  EXPECT_GT(max_mm, 0.005);  // and it is not an ideal motor
  std::printf("external plant: %zu samples, |r - y| mean %.4f mm, max %.4f mm, %zu lost-step event(s)\n",
              s.samples.size(), mean_mm, max_mm, lost_step_events);
}

TEST(ExternalPlantPrint, APlantThatExitsMidPrintStopsTheMachineWithItsReason) {
  SimRunOptions o;
  o.settle_s = 0.3;
  o.timeout_s = 30.0;
  auto r = run_simulated(with_plant("--exit-into-motion 400"), kProgram, o);  // 0.2 s into the first move
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_GT(r.value().commands, 0u);
  EXPECT_NE(r.value().error.find("external plant"), std::string::npos) << r.value().error;
  EXPECT_NE(r.value().error.find("exited with status 3"), std::string::npos) << r.value().error;
}

TEST(ExternalPlantPrint, AConfigThatNamesAMissingAxisOrARealMcuIsRefused) {
  // The default config with an external plant section naming an axis the machine does not have.
  auto yaml = config::to_yaml(config::default_config());
  const size_t at = yaml.find("simulator:\n");
  ASSERT_NE(at, std::string::npos);
  yaml.insert(at + 11, "  external_plant: {command: \"true\", axes: [x, w]}\n");
  auto cfg = config::load_config_text(yaml, "plant.yaml");
  ASSERT_FALSE(cfg.ok());
  EXPECT_NE(cfg.error().to_string().find("'w' is not an axis"), std::string::npos) << cfg.error().to_string();
  EXPECT_NE(cfg.error().to_string().find("plant.yaml:"), std::string::npos) << cfg.error().to_string();
}

}  // namespace
}  // namespace feedloop::engine
