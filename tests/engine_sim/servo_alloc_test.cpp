// Heap allocations in the servo cycle in steady motion, counted by interposing malloc (skipped
// under sanitizers, which own malloc): the executor and step pipeline allocate nothing, nor does
// the cycle with the MCU bridge (sessions, mock links, virtual MCUs, plants), on the exact
// open-loop path and on the sampled closed-loop path (feedforward + PI + lost-step detector +
// encoder guards).
#include <atomic>
#include <cstddef>
#include <cstdio>

#include <gtest/gtest.h>

#include "sim_rig.hpp"

#include "tests/common/malloc_counter.hpp"

namespace feedloop::engine {
namespace {

struct CountingSink final : stepgen::BatchSink {
  uint64_t steps = 0;
  void on_batch(const stepgen::StepBatch& b) override { steps += b.steps; }
};

[[maybe_unused]] constexpr const char* kLongMove = "G90\nG1 X200 Y150 F6000\n";

TEST(ServoAlloc, ExecutorAndPipelineAllocateNothingBridgeIsMeasured) {
#ifndef FEEDLOOP_COUNT_MALLOC
  GTEST_SKIP() << "malloc counting needs glibc and no sanitizer";
#else
  config::MachineConfig cfg = config::default_config();
  cfg.planner.allow_moves_before_homing = true;  // this test never homes (docs/homing.md)
  // Without MCUs: the servo cycle of the executor and the step pipeline alone.
  StepPipelineParams sp;
  sp.steps_per_mm = steps_per_mm(cfg);
  sp.mcu_clock_hz = static_cast<double>(cfg.stepgen.mcu_clock_hz);
  MotionOptions mo;
  mo.max_buffered_s = 1e6;
  mo.input_pause_flush_s = 0.0;
  auto sink = std::make_shared<CountingSink>();
  MotionExecutor ideal(planner_config(cfg), sp, sink, mo);
  std::atomic<bool> cancel{false};
  auto cmd1 = gcode::parse_line("G1 X200 Y150 F6000", SourceLocation{"t", 1, 0});
  ASSERT_TRUE(cmd1.ok());
  ASSERT_TRUE(ideal.execute(cmd1.value(), cancel).ok());
  ideal.idle_tick(cancel);
  int64_t now = 1'000'000'000;
  for (int i = 0; i < 300; ++i) ideal.servo_cycle(now += 1'000'000, false);
  g_mallocs = 0;
  g_counting = true;
  for (int i = 0; i < 500; ++i) ideal.servo_cycle(now += 1'000'000, false);
  g_counting = false;
  const long ideal_mallocs = g_mallocs.load();
  EXPECT_GT(sink->steps, 10000u);  // it moved
  EXPECT_EQ(ideal_mallocs, 0);

  // With the MCU bridge: sessions, mock links, virtual MCUs and plants in the cycle.
  testing::SimRig rig(cfg);
  ASSERT_TRUE(rig.wait_ready());
  ASSERT_EQ(rig.execute(kLongMove), "");
  rig.run_for(0.3);
  const uint64_t steps0 = rig.bridge->timing(0).steps_executed;
  g_mallocs = 0;
  g_counting = true;
  rig.run_for(0.5);
  g_counting = false;
  const double per_cycle = static_cast<double>(g_mallocs.load()) / 500.0;
  std::printf("servo cycle allocations in steady motion: executor + pipeline %ld in 500 cycles; with the MCU "
              "bridge (4 MCUs) %.2f per cycle\n",
              ideal_mallocs, per_cycle);
  EXPECT_GT(rig.bridge->timing(0).steps_executed, steps0 + 1000);  // it moved
  EXPECT_EQ(g_mallocs.load(), 0);
#endif
}

TEST(ServoAlloc, ClosedLoopCycleAllocatesNothing) {
#ifndef FEEDLOOP_COUNT_MALLOC
  GTEST_SKIP() << "malloc counting needs glibc and no sanitizer";
#else
  for (auto loop : {config::ControlLoop::device, config::ControlLoop::host})
  for (auto ff : {config::FeedforwardType::none, config::FeedforwardType::shaper, config::FeedforwardType::lpv}) {
    config::MachineConfig cfg = config::default_config();
    cfg.control.mode = config::ControlMode::pi;
    cfg.control.loop = loop;
    cfg.feedforward.type = ff;
    testing::SimRig rig(cfg);
    auto control = make_servo_control(cfg);
    ASSERT_TRUE(control.ok()) << control.error().message;
    ASSERT_TRUE(control.value());
    rig.ex->set_control(std::move(control.value()));
    ASSERT_TRUE(rig.wait_ready());
    ASSERT_EQ(rig.execute(kLongMove), "");
    rig.run_for(0.3);
    const uint64_t steps0 = rig.bridge->timing(0).steps_executed;
    g_mallocs = 0;
    g_counting = true;
    rig.run_for(0.5);
    g_counting = false;
    std::printf("closed loop (%s), feedforward %d: %ld allocations in 500 servo cycles\n",
                loop == config::ControlLoop::host ? "host" : "device", static_cast<int>(ff), g_mallocs.load());
    EXPECT_GT(rig.bridge->timing(0).steps_executed, steps0 + 1000);  // it moved
    EXPECT_EQ(g_mallocs.load(), 0);
  }
#endif
}

}  // namespace
}  // namespace feedloop::engine
