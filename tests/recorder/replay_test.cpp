// Recording a simulated print through the daemon's motion stack in virtual time, and replaying it:
// the replay's step stream is bit-identical to the recording's with the same config, differs
// (with the first difference named) with another motion config, and the encoder residual sees
// a simulator change that the step stream does not. Damaged logs are clear errors.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "config/config.hpp"
#include "recorder/log_reader.hpp"
#include "recorder/replay.hpp"
#include "recorder/step_stream.hpp"
#include "recorder/trace_export.hpp"
#include "recorder_test_util.hpp"

namespace feedloop::recorder {
namespace {

using testing::ScratchDir;

// About 3 s of printing: an extruded square, a diagonal and a small zig-zag, with M400 in the
// middle (a motion stop and a second motion start: two time anchors).
std::vector<std::string> test_print() {
  std::vector<std::string> g = {"; replay test print", "G90", "M83", "G1 Z0.3 F600", "G1 X20 Y20 F9000"};
  g.push_back("G1 X60 Y20 E2 F4800");
  g.push_back("G1 X60 Y60 E2");
  g.push_back("G1 X20 Y60 E2");
  g.push_back("G1 X20 Y20 E2");
  g.push_back("M400");
  g.push_back("G1 X50 Y45 F9000");
  for (int i = 0; i < 10; ++i) g.push_back("G1 X" + std::to_string(52 + 2 * i) + " Y" + std::to_string(i % 2 ? 45 : 50) + " E0.2 F3000");
  g.push_back("G1 X10 Y10 F9000");
  return g;
}

// Open loop, so that a change of the simulated plant does not change the commanded steps.
config::MachineConfig open_loop_config() {
  config::MachineConfig cfg = config::default_config();
  cfg.planner.allow_moves_before_homing = true;  // this fixture never homes (docs/homing.md)
  cfg.control.mode = config::ControlMode::open_loop;
  return cfg;
}

struct Recorded {
  ScratchDir dir{"replay"};
  VirtualPrintResult run;
  std::string config_yaml;
};

void record(Recorded& r, const config::MachineConfig& cfg) {
  r.config_yaml = config::to_yaml(cfg);
  auto run = record_virtual_print(cfg, r.config_yaml, test_print(), r.dir.str(), "square");
  ASSERT_TRUE(run.ok()) << run.error().to_string();
  r.run = std::move(*run);
}

std::string write_config(const ScratchDir& dir, const config::MachineConfig& cfg) {
  const std::string path = dir.file("other.yaml");
  std::ofstream(path) << config::to_yaml(cfg);
  return path;
}

TEST(ReplayTest, RecordsEveryKindOfRecordOfASimulatedPrint) {
  Recorded r;
  record(r, open_loop_config());
  ASSERT_EQ(r.run.logs.size(), 1u);
  EXPECT_EQ(r.run.rejected, 0u) << r.run.first_error;
  EXPECT_EQ(r.run.anchors, 2u);  // the print starts, stops at M400, starts again
  EXPECT_EQ(r.run.recorder.dropped, (std::array<uint64_t, kStreams>{}));
  auto p = read_recorded_print(r.run.logs);
  ASSERT_TRUE(p.ok()) << p.error().to_string();
  EXPECT_EQ(p->gcode.size(), test_print().size());
  EXPECT_EQ(p->gcode[5].text, "G1 X60 Y20 E2 F4800");
  EXPECT_GE(p->moves.size(), 16u);
  EXPECT_EQ(p->anchors_s.size(), 2u);
  EXPECT_EQ(p->header.config_yaml, r.config_yaml);
  // Encoders on x and y (0.49 um AS5311), none on z and e.
  ASSERT_EQ(p->encoders.size(), 4u);
  // Every sample the MCUs took (one per servo period): thousands each.
  EXPECT_GT(p->encoders[0].size(), 200u);
  EXPECT_GT(p->encoders[1].size(), 200u);
  EXPECT_EQ(p->encoders[2].size(), 0u);
  auto steps = read_step_streams(r.run.logs);
  ASSERT_TRUE(steps.ok());
  // x travels 20 + 40 + 40 + 30 + 20 + 40 + 30 + 42 mm or so: thousands of steps at 94.3 steps/mm.
  uint64_t x_steps = 0;
  for (const StepRunRecord& run : steps->runs[0]) x_steps += run.run.count;
  EXPECT_GT(x_steps, 15000u);
  // The last recorded x encoder reading is near the last commanded x position (10 mm). Samples
  // are taken while the motion is anchored, which ends with the plan: the open-loop carriage
  // still lags its deceleration then (measured 0.17 mm).
  const double x_end_mm = static_cast<double>(p->encoders[0].back().counts) * 0.00049;
  EXPECT_NEAR(x_end_mm, 10.0, 0.3);
}

// Every encoder sample is recorded at the MCU clock of its taking (EngineRecording::
// on_encoder_sample): one per servo period, evenly spaced on the steps' time line. Before, each
// servo cycle recorded its latest reading (up to a report, 10 periods, old) stamped with the
// cycle's time, and only when it changed: ~100 Hz, and the exported carriage lagged its steps by
// 5-8 ms, which the identification read as dynamics.
TEST(ReplayTest, EncoderSamplesAreRecordedAtTheirMcuClockEveryServoPeriod) {
  Recorded r;
  record(r, open_loop_config());
  auto p = read_recorded_print(r.run.logs);
  ASSERT_TRUE(p.ok()) << p.error().to_string();
  const auto& x = p->encoders[0];
  ASSERT_GT(x.size(), 100u);
  const double clock_hz = static_cast<double>(p->header.joints[0].clock_hz);
  const double span_s = static_cast<double>(x.back().clock - x.front().clock) / clock_hz;
  // One sample per 1 ms servo period over the span (the mock MCUs' +-50 ppm clocks).
  EXPECT_NEAR(static_cast<double>(x.size() - 1), span_s * 1000.0, 2.0);
  for (size_t i = 1; i < x.size(); ++i) {
    const double gap_ms = static_cast<double>(x[i].clock - x[i - 1].clock) / clock_hz * 1e3;
    ASSERT_NEAR(gap_ms, 1.0, 0.01) << "sample " << i;
  }
  // The export: the joint's measured span, and at rest at the end the carriage on its steps.
  auto t = build_trace(r.run.logs, ExportOptions{});
  ASSERT_TRUE(t.ok()) << t.error().to_string();
  ASSERT_EQ(t->meas_span_s.size(), t->joints.size());
  EXPECT_NEAR(t->meas_span_s[0].second - t->meas_span_s[0].first, span_s, 1e-6);
}

TEST(ReplayTest, SameConfigGivesABitIdenticalStepStreamAndZeroResidual) {
  Recorded r;
  record(r, open_loop_config());
  auto rep = replay_print(r.run.logs);
  ASSERT_TRUE(rep.ok()) << rep.error().to_string();
  std::printf("%s", rep->to_text().c_str());
  EXPECT_EQ(rep->config_source, "log header");
  EXPECT_FALSE(rep->move_mismatch) << *rep->move_mismatch;
  EXPECT_FALSE(rep->anchor_mismatch) << *rep->anchor_mismatch;
  EXPECT_TRUE(rep->steps_identical()) << *rep->step_mismatch;
  EXPECT_GT(rep->steps_compared, 30000u);
  ASSERT_EQ(rep->residuals.size(), 2u);  // x and y have encoders
  for (const JointResidual& j : rep->residuals) {
    EXPECT_GT(j.samples, 200u) << j.joint;
    EXPECT_EQ(j.rms_um, 0.0) << j.joint;  // the simulator is deterministic (seeded noise)
  }
}

// Disabled for now: with the closed-loop (sampled) servo path of the current engine, destroying
// the motion stack after the run crashes in ~ServoControl (invalid free of a DiscreteLtiFilter's
// vector; valgrind), before the replay. Enable once the sampled path settles.
TEST(ReplayTest, ClosedLoopPrintReplaysBitIdentically) {
  Recorded r;
  config::MachineConfig pi_cfg = config::default_config();
  pi_cfg.planner.allow_moves_before_homing = true;  // this fixture never homes (docs/homing.md)
  record(r, pi_cfg);  // PI on the encoders: the steps depend on the plant
  auto rep = replay_print(r.run.logs);
  ASSERT_TRUE(rep.ok()) << rep.error().to_string();
  EXPECT_TRUE(rep->steps_identical()) << *rep->step_mismatch;
  EXPECT_GT(rep->steps_compared, 30000u);
}

TEST(ReplayTest, OtherMotionConfigNamesTheFirstDifferentStep) {
  Recorded r;
  record(r, open_loop_config());
  config::MachineConfig other = open_loop_config();
  other.planner.max_accel_mm_s2 = 2000.0;  // was 3000
  ReplayOptions o;
  o.config_path = write_config(r.dir, other);
  auto rep = replay_print(r.run.logs, o);
  ASSERT_TRUE(rep.ok()) << rep.error().to_string();
  std::printf("%s", rep->to_text().c_str());
  EXPECT_EQ(rep->config_source, o.config_path);
  ASSERT_TRUE(rep->move_mismatch);
  ASSERT_FALSE(rep->steps_identical());
  EXPECT_NE(rep->step_mismatch->find("joint "), std::string::npos) << *rep->step_mismatch;
}

TEST(ReplayTest, ResidualSeesAPlantEffectThatTheStepsDoNot) {
  Recorded r;
  config::MachineConfig plant = open_loop_config();
  config::PeriodicPositionConfig pp;
  pp.period_mm = 10.0;
  pp.amplitude_um = 25.0;
  pp.axes = {"x"};
  plant.simulator.effects.periodic_position = pp;
  record(r, plant);  // "the machine": x has a 25 um periodic position error
  ReplayOptions o;
  o.config_path = write_config(r.dir, open_loop_config());  // the model: no such effect
  auto rep = replay_print(r.run.logs, o);
  ASSERT_TRUE(rep.ok()) << rep.error().to_string();
  std::printf("%s", rep->to_text().c_str());
  EXPECT_TRUE(rep->steps_identical()) << *rep->step_mismatch;
  ASSERT_EQ(rep->residuals.size(), 2u);
  const JointResidual& x = rep->residuals[0];
  const JointResidual& y = rep->residuals[1];
  EXPECT_EQ(x.joint, "x");
  // A sine of 25 um amplitude has an RMS of 17.7 um and a max of 25 um (sampled while moving).
  EXPECT_GT(x.rms_um, 10.0);
  EXPECT_LT(x.rms_um, 20.0);
  EXPECT_GT(x.max_abs_um, 20.0);
  EXPECT_LT(x.max_abs_um, 27.0);
  EXPECT_EQ(y.rms_um, 0.0);
}

TEST(ReplayTest, EncoderResidualHoldsTheSimulatedReading) {
  // Simulated: 0 counts from clock 100, 10 counts from clock 200. Recorded (first step 1000 later):
  // at 1150 (= 150) 2 counts -> +2; at 1250 (= 250) 10 -> 0; at 1050 (= 50, before the data): skipped.
  const std::vector<EncoderRecord> sim = {{0, 100, 0}, {0, 200, 10}};
  const std::vector<EncoderRecord> rec = {{0, 1050, 5}, {0, 1150, 2}, {0, 1250, 10}};
  const JointResidual r = encoder_residual("x", rec, 1000, sim, 0, 0.001);
  EXPECT_EQ(r.samples, 2u);
  EXPECT_DOUBLE_EQ(r.max_abs_um, 2.0);
  EXPECT_DOUBLE_EQ(r.mean_um, 1.0);
  EXPECT_DOUBLE_EQ(r.rms_um, std::sqrt(2.0));
}

TEST(ReplayTest, DamagedLogsAreClearErrors) {
  Recorded r;
  record(r, open_loop_config());
  const std::string log = r.run.logs[0];
  const auto size = std::filesystem::file_size(log);

  auto missing = replay_print({r.dir.file("nope.flrec")});
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().to_string().find("nope.flrec: no such file"), std::string::npos);

  const std::string cut = r.dir.file("cut.flrec");
  std::filesystem::copy_file(log, cut);
  std::filesystem::resize_file(cut, size - 100);
  auto truncated = replay_print({cut});
  ASSERT_FALSE(truncated.ok());
  EXPECT_NE(truncated.error().to_string().find("truncated block at byte offset"), std::string::npos)
      << truncated.error().to_string();

  const std::string bad = r.dir.file("bad.flrec");
  std::filesystem::copy_file(log, bad);
  {
    std::fstream f(bad, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(static_cast<std::streamoff>(size / 2));
    char c = 0;
    f.read(&c, 1);
    f.seekp(static_cast<std::streamoff>(size / 2));
    c = static_cast<char>(c ^ 0x5a);
    f.write(&c, 1);
  }
  auto corrupt = replay_print({bad});
  ASSERT_FALSE(corrupt.ok());
  const std::string msg = corrupt.error().to_string();
  EXPECT_NE(msg.find("byte offset"), std::string::npos) << msg;
  EXPECT_NE(msg.find("bad.flrec"), std::string::npos) << msg;

  const std::string junk = r.dir.file("junk.flrec");
  std::ofstream(junk) << "this is not a log";
  auto not_log = replay_print({junk});
  ASSERT_FALSE(not_log.ok());
  EXPECT_NE(not_log.error().to_string().find("bad magic at byte offset 0"), std::string::npos)
      << not_log.error().to_string();
}

}  // namespace
}  // namespace feedloop::recorder
