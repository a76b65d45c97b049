// The DC-servo executor's servo cycle (plant RK4 substeps, waypoint queue, path window, the
// maneuvering servo, telemetry) allocates nothing in steady motion: malloc counted around 5000
// cycles (1 s at 5 kHz) while the extruder follows a zigzag with sharp corners.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <string>

#include "config/config.hpp"
#include "engine/maneuver_executor.hpp"
#include "gcode/parser.hpp"

#include "tests/common/malloc_counter.hpp"

namespace feedloop::engine {
namespace {

TEST(DcServoAlloc, ServoCycleAllocatesNothing) {
#ifndef FEEDLOOP_COUNT_MALLOC
  GTEST_SKIP() << "malloc counting needs glibc and no sanitizer";
#else
  auto cfg = config::load_config_file(FEEDLOOP_SOURCE_DIR "/config/examples/dc_servo_sim.yaml");
  ASSERT_TRUE(cfg.ok()) << cfg.error().to_string();
  cfg->planner.allow_moves_before_homing = true;  // this test never homes (docs/homing.md)
  ManeuverExecutorOptions o;
  o.max_buffered_s = 1e6;  // execute() never waits for the servo (same thread here)
  auto made = ManeuverExecutor::create(*cfg, o);
  ASSERT_TRUE(made.ok()) << made.error().message;
  ManeuverExecutor& ex = *made.value();
  std::atomic<bool> cancel{false};
  // A zigzag of 150 sharp corners, 200 mm: longer than the 1.3 s counted.
  std::string program = "G90\nG1 X10 Y10 F6000\n";
  for (int i = 1; i <= 150; ++i)
    program += "G1 X" + std::to_string(10 + i) + " Y" + std::to_string(i % 2 == 0 ? 10 : 11) + "\n";
  int n = 0;
  size_t at = 0;
  while (at < program.size()) {
    const size_t end = program.find('\n', at);
    auto cmd = gcode::parse_line(program.substr(at, end - at), SourceLocation{"t", ++n, 0});
    ASSERT_TRUE(cmd.ok());
    ASSERT_TRUE(ex.execute(cmd.value(), cancel).ok());
    at = end + 1;
  }
  ex.idle_tick(cancel);  // releases the lookahead's tail (the machine would run dry)
  const int64_t period = static_cast<int64_t>(1e9 * ex.servo_period_s());
  int64_t now = 1'000'000'000;
  for (int i = 0; i < 1500; ++i) ex.servo_cycle(now += period, false);  // 0.3 s: well under way
  const uint64_t seg0 = ex.telemetry().segments_entered.load();
  g_mallocs = 0;
  g_counting = true;
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < 5000; ++i) ex.servo_cycle(now += period, false);
  const double cycle_us = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count() / 5000;
  g_counting = false;
  std::printf("servo cycle cost (controller RK4 + plant RK4 substeps): %.2f us per cycle at %.0f Hz\n", cycle_us,
              1.0 / ex.servo_period_s());
  const long mallocs = g_mallocs.load();
  const uint64_t seg1 = ex.telemetry().segments_entered.load();
  std::printf("DC-servo servo cycle: %ld allocations in 5000 cycles; %llu segments entered meanwhile, "
              "max cross-track %.3f um\n",
              mallocs, static_cast<unsigned long long>(seg1 - seg0), ex.telemetry().max_cross_track_mm.load() * 1e3);
  EXPECT_EQ(mallocs, 0);
  EXPECT_GT(seg1 - seg0, 20u);  // it was moving through corners
  EXPECT_FALSE(ex.telemetry().holding.load());
#endif
}

}  // namespace
}  // namespace feedloop::engine
