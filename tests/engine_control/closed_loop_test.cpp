// The servo loop's control law on the simulated printer, through the daemon's own pipeline
// (engine::run_simulated: executor, MCU bridge, mock transports, virtual MCUs, the nonlinear
// stepper + belt plant with its encoders). The plant contains what the controller's model lacks:
// the stepper's sine torque law (it can slip), quantised encoders, and here a steps/mm error or
// a too-high acceleration.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "config/config.hpp"
#include "engine/sim_run.hpp"

namespace feedloop::engine {
namespace {

struct Errors {
  double final_x_mm = 0.0, final_y_mm = 0.0;  // carriage - target at the end
  double mean_mm = 0.0, max_mm = 0.0;         // |desired - actual| over the run (XY)
  size_t samples = 0;
};

Errors errors_of(const SimRunResult& r, double x_end, double y_end) {
  Errors e;
  double sum = 0.0;
  for (const SimRunSample& s : r.samples) {
    const double dx = s.servo.desired_mm[0] - s.actual_mm[0];
    const double dy = s.servo.desired_mm[1] - s.actual_mm[1];
    const double d = std::hypot(dx, dy);
    sum += d;
    e.max_mm = std::max(e.max_mm, d);
  }
  e.samples = r.samples.size();
  e.mean_mm = e.samples ? sum / static_cast<double>(e.samples) : 0.0;
  if (!r.samples.empty()) {
    e.final_x_mm = r.samples.back().actual_mm[0] - x_end;
    e.final_y_mm = r.samples.back().actual_mm[1] - y_end;
  }
  return e;
}

std::vector<std::string> lines(std::initializer_list<const char*> l) { return {l.begin(), l.end()}; }

config::MachineConfig with_mode(config::ControlMode mode) {
  config::MachineConfig cfg = config::default_config();
  cfg.control.mode = mode;
  return cfg;
}

TEST(ClosedLoop, PiRemovesAConstantStepsPerMmError) {
  const auto program = lines({"G90", "G1 X40 Y30 F6000", "G4 P300"});
  double open_loop_mm = 0.0;
  for (auto mode : {config::ControlMode::open_loop, config::ControlMode::pi}) {
    config::MachineConfig cfg = with_mode(mode);
    cfg.simulator.effects.scale_error = config::ScaleErrorConfig{1.01, {}};  // 1 % steps/mm error
    SimRunOptions o;
    o.settle_s = 0.5;
    auto r = run_simulated(cfg, program, o);
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_EQ(r.value().error, "");
    const Errors e = errors_of(r.value(), 40.0, 30.0);
    std::printf("%s: final error x %.4f mm, y %.4f mm (%zu samples)\n",
                mode == config::ControlMode::pi ? "PI       " : "open loop", e.final_x_mm, e.final_y_mm, e.samples);
    const double err_mm = std::hypot(e.final_x_mm, e.final_y_mm);
    if (mode == config::ControlMode::open_loop) {
      open_loop_mm = err_mm;
      EXPECT_GT(std::fabs(e.final_x_mm), 0.25);  // ~1 % of the 40 mm travel
    } else {
      // Within two steps (10.6 um each): the integrator hunts by a step at rest.
      EXPECT_LT(std::fabs(e.final_x_mm), 0.022);
      EXPECT_LT(std::fabs(e.final_y_mm), 0.022);
      EXPECT_LT(err_mm, 0.05 * open_loop_mm);
    }
  }
}

}  // namespace
}  // namespace feedloop::engine
