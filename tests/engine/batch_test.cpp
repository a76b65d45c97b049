// Batch mode: two threads give bit-identical output to one; the delta's step streams start at
// the first move (regression: they started at 0 mm and the first segment jumped ~280 mm); the
// step-time error bound on generated programs (the corpus version is step_error_corpus_test).
#include <gtest/gtest.h>

#include "tests/engine/batch_support.hpp"

namespace feedloop::engine::testing {
namespace {

void expect_identical(const std::string& path, const config::MachineConfig& cfg) {
  BatchHasher h1, h2;
  BatchOptions o1, o2;
  o1.threads = 1;
  o1.batch_tap = &h1;
  o2.threads = 2;
  o2.batch_tap = &h2;
  auto a = run_batch(path, cfg, o1);
  auto b = run_batch(path, cfg, o2);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_GT(a->total_steps, 10000u);
  EXPECT_EQ(a->moves, b->moves);
  EXPECT_EQ(a->wire_bytes, b->wire_bytes);
  for (int j = 0; j < kJoints; ++j) {
    const JointStepStats &x = a->joints[static_cast<size_t>(j)], &y = b->joints[static_cast<size_t>(j)];
    EXPECT_EQ(x.steps, y.steps) << "joint " << j;
    EXPECT_EQ(x.runs, y.runs) << "joint " << j;
    EXPECT_EQ(x.batches, y.batches) << "joint " << j;
    EXPECT_EQ(x.body_bytes, y.body_bytes) << "joint " << j;
    EXPECT_EQ(x.max_step_rate_hz, y.max_step_rate_hz) << "joint " << j;
    EXPECT_EQ(h1.hash(j), h2.hash(j)) << "joint " << j << ": the batch streams differ";
  }
}

TEST(BatchThreads, TwoThreadsGiveTheSameRunsAsOne) {
  const std::string path = write_temp("spiral_cart.gcode", spiral_gcode(100, 100, 30, 1000));
  expect_identical(path, config::default_config());
}

// The stages bench/batch times: each does what the one before it does, and one thing more.
TEST(BatchStages, EachStageDoesTheWorkOfThoseBeforeIt) {
  const std::string path = write_temp("spiral_stages.gcode", spiral_gcode(100, 100, 30, 500));
  const config::MachineConfig cfg = config::default_config();
  BatchSummary by_stage[5];
  for (int st = 0; st < 5; ++st) {
    BatchOptions o;
    o.last_stage = static_cast<BatchStage>(st);
    auto r = run_batch(path, cfg, o);
    ASSERT_TRUE(r.ok()) << r.error().to_string();
    by_stage[st] = *r;
  }
  const BatchSummary &parse = by_stage[0], &plan = by_stage[1], &times = by_stage[2],
                     &comp = by_stage[3], &all = by_stage[4];
  EXPECT_GT(all.total_steps, 10000u);
  for (const BatchSummary* s : {&parse, &plan, &times, &comp}) {
    EXPECT_EQ(s->lines, all.lines);
    EXPECT_EQ(s->commands, all.commands);
  }
  EXPECT_EQ(parse.moves, 0u);
  EXPECT_EQ(plan.moves, all.moves);
  EXPECT_EQ(plan.total_steps, 0u);
  EXPECT_EQ(times.total_steps, all.total_steps);
  EXPECT_EQ(times.joints[0].runs, 0u);
  EXPECT_EQ(comp.total_steps, all.total_steps);
  for (int j = 0; j < kJoints; ++j)
    EXPECT_EQ(comp.joints[static_cast<size_t>(j)].runs, all.joints[static_cast<size_t>(j)].runs);
  EXPECT_EQ(comp.wire_bytes, 0u);
  EXPECT_GT(all.wire_bytes, 0u);
}

TEST(BatchThreads, TwoThreadsGiveTheSameRunsAsOneOnTheCorpusCube) {
  const std::string path = std::string(FEEDLOOP_SHARED_DIR) + "/gcode/cube20_cartesian.gcode";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "corpus absent: " << path;
  expect_identical(path, config::default_config());
}

TEST(BatchDelta, StepStreamsStartAtTheFirstMove) {
  const config::MachineConfig cfg = delta_config();
  ASSERT_EQ(cfg.kinematics, config::Kinematics::delta);
  const std::string path = write_temp("spiral_delta.gcode", spiral_gcode(0, 0, 70, 600));
  auto r = run_checked(path, cfg);
  ASSERT_TRUE(r.ok()) << r.error().to_string();
  const BatchSummary& s = r->summary;
  EXPECT_EQ(s.rejected, 0);
  EXPECT_EQ(s.check_failures, 0u);
  for (int j = 0; j < 3; ++j) {
    const JointStepStats& js = s.joints[static_cast<size_t>(j)];
    // Carriages move at most a few times the effector's 150 mm/s: 80 steps/mm * 450 mm/s = 36 kHz.
    // The bug made thousands of steps within a microsecond (~1 GHz).
    EXPECT_LT(js.max_step_rate_hz, 40e3) << "carriage " << j;
    EXPECT_GT(js.steps, 1000u);
  }
  EXPECT_EQ(r->not_found, 0u);
  EXPECT_LE(r->max_error_us, cfg.stepgen.max_step_error_us + 1e-5);  // + double resolution of print time
  EXPECT_GT(r->max_error_us, 0.0);
  std::printf("delta spiral: %llu steps, max step-time error %.3f us, %.3f B/step\n",
              static_cast<unsigned long long>(s.total_steps), r->max_error_us, s.wire_bytes_per_step);
}

TEST(BatchStepError, GeneratedCartesianProgramWithinTheBound) {
  const config::MachineConfig cfg = config::default_config();
  const std::string path = write_temp("spiral_cart_err.gcode", spiral_gcode(100, 100, 30, 1000));
  for (int threads : {1, 2}) {
    auto r = run_checked(path, cfg, threads);
    ASSERT_TRUE(r.ok()) << r.error().to_string();
    EXPECT_EQ(r->summary.check_failures, 0u);
    EXPECT_EQ(r->not_found, 0u);
    uint64_t decoded = 0;
    for (int j = 0; j < kJoints; ++j) {
      EXPECT_EQ(r->joints[static_cast<size_t>(j)].steps, r->summary.joints[static_cast<size_t>(j)].steps);
      decoded += r->joints[static_cast<size_t>(j)].steps;
    }
    EXPECT_EQ(decoded, r->summary.total_steps);
    EXPECT_LE(r->max_error_us, cfg.stepgen.max_step_error_us + 1e-5);  // + double resolution of print time
    // The compressor uses the error budget (a bound that is never approached tests nothing).
    EXPECT_GT(r->max_error_us, 0.5 * cfg.stepgen.max_step_error_us);
  }
}

// Pressure advance in batch mode (extruder.pressure_advance): the extruder's steps follow the
// advance's segments within the bound, one and two threads agree, X/Y/Z are untouched and the
// extruder makes more steps (the advance and its return at every speed change).
TEST(BatchPressureAdvance, ExtruderFollowsTheAdvanceWithinTheBoundOtherJointsUnchanged) {
  const std::string path = write_temp("spiral_pa.gcode", spiral_gcode(100, 100, 30, 600));
  const config::MachineConfig plain = config::default_config();
  config::MachineConfig cfg = plain;
  cfg.extruder.pressure_advance = 0.05;
  expect_identical(path, cfg);
  auto a = run_checked(path, plain);
  auto b = run_checked(path, cfg);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(b->not_found, 0u);
  EXPECT_EQ(b->summary.check_failures, 0u);
  EXPECT_LE(b->max_error_us, cfg.stepgen.max_step_error_us + 1e-5);
  for (int j = 0; j < 3; ++j)
    EXPECT_EQ(a->summary.joints[static_cast<size_t>(j)].steps, b->summary.joints[static_cast<size_t>(j)].steps) << j;
  std::printf("extruder steps: %llu without, %llu with K = 0.05 s\n",
              static_cast<unsigned long long>(a->summary.joints[3].steps),
              static_cast<unsigned long long>(b->summary.joints[3].steps));
  EXPECT_GT(b->summary.joints[3].steps, a->summary.joints[3].steps);
}

TEST(BatchStepError, ATighterBoundIsHonouredToo) {
  config::MachineConfig cfg = config::default_config();
  cfg.stepgen.max_step_error_us = 1.0;
  const std::string path = write_temp("spiral_cart_tight.gcode", spiral_gcode(100, 100, 30, 500));
  auto r = run_checked(path, cfg);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->not_found, 0u);
  EXPECT_LE(r->max_error_us, 1.0 + 1e-5);
  EXPECT_GT(r->max_error_us, 0.5);
}

}  // namespace
}  // namespace feedloop::engine::testing
