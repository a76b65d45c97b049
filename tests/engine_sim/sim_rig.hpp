// Test rig: the motion executor with the MCU bridge (sessions, mock transports, virtual MCUs,
// plant simulator) built from a config, driven like the servo thread drives it: servo_cycle()
// every millisecond of virtual time, commands executed on the test's thread in between.
#pragma once

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <memory>
#include <sstream>
#include <string>

#include "config/config.hpp"
#include "engine/config_mapping.hpp"
#include "engine/mcu_bridge.hpp"
#include "engine/motion_executor.hpp"
#include "gcode/parser.hpp"

namespace feedloop::engine::testing {

struct SimRig {
  config::MachineConfig cfg;
  std::shared_ptr<McuBridge> bridge;
  std::unique_ptr<MotionExecutor> ex;
  std::atomic<bool> cancel{false};
  int64_t now_ns = 1'000'000'000;  // host clock (any epoch)
  int64_t period_ns = 1'000'000;

  explicit SimRig(const config::MachineConfig& c, const McuBridgeOptions& o = {}) : cfg(c) {
    cfg.planner.allow_moves_before_homing = true;  // the rig's programs never home (docs/homing.md)
    auto b = make_mcu_bridge(cfg, o);
    EXPECT_TRUE(b.ok()) << (b.ok() ? "" : b.error().message);
    bridge = std::move(b.value());
    StepPipelineParams sp;
    sp.steps_per_mm = steps_per_mm(cfg);
    sp.mcu_clock_hz = static_cast<double>(cfg.stepgen.mcu_clock_hz);
    sp.max_step_error_us = cfg.stepgen.max_step_error_us;
    MotionOptions mo;
    mo.lead_s = cfg.stepgen.queue_ahead_ms * 1e-3;
    mo.max_buffered_s = 1e6;       // execute() never waits for the servo (same thread here)
    mo.input_pause_flush_s = 0.0;  // idle_tick() releases the lookahead at once
    ex = std::make_unique<MotionExecutor>(planner_config(cfg), sp, bridge, mo);
    ex->set_backend(bridge.get());
    ex->set_inline_driver([this] { cycle(); });  // G28, M400: this thread runs the servo cycles
  }
  double now_s() const { return static_cast<double>(now_ns) * 1e-9; }
  void cycle() {
    now_ns += period_ns;
    ex->servo_cycle(now_ns, false);
  }
  void run_for(double s) {
    const int64_t end = now_ns + static_cast<int64_t>(s * 1e9);
    while (now_ns < end) cycle();
  }
  // Waits (in virtual time) until the MCUs are identified and their clocks settled.
  bool wait_ready(double max_s = 5.0) {
    const int64_t end = now_ns + static_cast<int64_t>(max_s * 1e9);
    while (now_ns < end && !bridge->ready()) cycle();
    return bridge->ready();
  }
  // Executes each line; returns the first error (empty when all succeeded).
  std::string execute(const std::string& program) {
    std::istringstream in(program);
    std::string line;
    int n = 0;
    while (std::getline(in, line)) {
      auto cmd = gcode::parse_line(line, SourceLocation{"test.gcode", ++n, 0});
      if (!cmd.ok()) return cmd.error().message;
      if (Status st = ex->execute(cmd.value(), cancel); !st) return st.error().message;
    }
    ex->idle_tick(cancel);  // releases the lookahead's tail
    return {};
  }
  // Runs until nothing is pending, then `settle_s` more. Returns false on timeout.
  bool run_until_idle(double max_s = 30.0, double settle_s = 0.5) {
    const int64_t end = now_ns + static_cast<int64_t>(max_s * 1e9);
    while (now_ns < end && ex->motion_pending()) cycle();
    run_for(settle_s);
    return !ex->motion_pending();
  }
};

}  // namespace feedloop::engine::testing
