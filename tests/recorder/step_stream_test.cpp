// Step stream comparison (for replay): identical streams compare equal even when split into runs
// differently; a one-tick change or a missing step is found at the right joint and step.
// Options from the printer config.
#include <gtest/gtest.h>

#include "config/config.hpp"
#include "recorder/options_from_config.hpp"
#include "recorder/recorder.hpp"
#include "recorder/step_stream.hpp"
#include "recorder_test_util.hpp"

namespace feedloop::recorder {
namespace {

std::string record_runs(const testing::ScratchDir& dir, const std::string& name,
                        const std::vector<testing::RunItem>& runs, int joint) {
  auto rec = Recorder::create(testing::test_options(dir.str()));
  EXPECT_TRUE(rec.ok());
  EXPECT_TRUE((*rec)->start_print(name).ok());
  for (const auto& r : runs) (*rec)->writer(Stream::servo).step_run(joint, r.start_clock, r.run);
  EXPECT_TRUE((*rec)->end_print().ok());
  for (const std::string& log : dir.logs())
    if (log.find("_" + name + "_p000") != std::string::npos) return log;
  ADD_FAILURE() << "no log for " << name;
  return {};
}

TEST(RecorderStepStream, IdenticalDifferentlySplitAndChanged) {
  testing::ScratchDir dir("steps");
  const auto runs = testing::trapezoid_runs(20, 80.0, 72e6);
  ASSERT_GT(runs.size(), 100u);
  const std::string a = record_runs(dir, "a", runs, 1);

  // Same steps, but the 10th run split in two (constant-interval parts keep the step law).
  std::vector<testing::RunItem> split;
  int split_done = 0;
  for (const auto& r : runs) {
    if (!split_done && r.run.count >= 4 && r.run.add_ticks == 0) {
      stepgen::StepRun first = r.run, second = r.run;
      first.count = 2;
      second.count = r.run.count - 2;
      split.push_back({r.start_clock, first});
      split.push_back({stepgen::run_end_clock(r.start_clock, first), second});
      split_done = 1;
    } else {
      split.push_back(r);
    }
  }
  ASSERT_TRUE(split_done);
  const std::string b = record_runs(dir, "b", split, 1);

  // One tick later at run 50.
  auto moved = runs;
  moved[50].run.interval_ticks += 1;
  const std::string c = record_runs(dir, "c", moved, 1);

  // The last run one step shorter.
  auto shorter = runs;
  shorter.back().run.count -= 1;
  const std::string d = record_runs(dir, "d", shorter, 1);

  auto sa = read_step_streams({a}), sb = read_step_streams({b}), sc = read_step_streams({c}), sd = read_step_streams({d});
  ASSERT_TRUE(sa.ok() && sb.ok() && sc.ok() && sd.ok());
  EXPECT_FALSE(compare_step_streams(*sa, *sa).has_value());
  EXPECT_FALSE(compare_step_streams(*sa, *sb).has_value());

  uint64_t steps_before_50 = 0;
  for (size_t i = 0; i < 50; ++i) steps_before_50 += runs[i].run.count;
  auto mc = compare_step_streams(*sa, *sc);
  ASSERT_TRUE(mc.has_value());
  EXPECT_EQ(mc->joint, 1);
  EXPECT_EQ(mc->step, steps_before_50);  // the first step of run 50
  EXPECT_EQ(mc->clock_b - mc->clock_a, 1);
  EXPECT_NE(mc->to_string(sa->joints).find("joint y, step " + std::to_string(steps_before_50)), std::string::npos);

  uint64_t total = 0;
  for (const auto& r : runs) total += r.run.count;
  auto md = compare_step_streams(*sa, *sd);
  ASSERT_TRUE(md.has_value());
  EXPECT_EQ(md->step, total - 1);
  EXPECT_EQ(md->dir_b, 0);
  EXPECT_NE(md->to_string(sa->joints).find("stream ended"), std::string::npos);
}

TEST(RecorderStepStream, OptionsFromTheDefaultConfig) {
  const config::MachineConfig& cfg = config::default_config();
  config::PathVars vars{"/run/feedloop-test", "/var/lib/feedloop-test"};
  std::vector<std::string> names;
  for (const auto& a : cfg.axes) names.push_back(a.name);
  auto o = recorder_options_from_config(cfg, std::string(config::default_config_yaml()), names, vars);
  ASSERT_TRUE(o.ok()) << o.error().to_string();
  ASSERT_EQ(o->joints.size(), cfg.axes.size());
  for (size_t i = 0; i < cfg.axes.size(); ++i) {
    EXPECT_EQ(o->joints[i].name, cfg.axes[i].name);
    EXPECT_EQ(o->joints[i].steps_per_mm, cfg.axes[i].steps_per_mm);
    EXPECT_EQ(o->joints[i].encoder_resolution_mm > 0.0, cfg.axes[i].encoder.has_value());
    EXPECT_GT(o->joints[i].clock_hz, 0);
  }
  if (cfg.recorder.enabled) {
    EXPECT_EQ(o->config.directory.find("${"), std::string::npos);
    EXPECT_EQ(o->config.directory.rfind("/var/lib/feedloop-test", 0), 0u) << o->config.directory;
  }
  EXPECT_EQ(o->config_yaml, std::string(config::default_config_yaml()));
  auto bad = recorder_options_from_config(cfg, "", {"x", "w"}, vars);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("joint 'w'"), std::string::npos);
}

}  // namespace
}  // namespace feedloop::recorder
