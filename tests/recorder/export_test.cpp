// Trace CSV v1 export: cmd reconstructed exactly from the step runs (and origins) at each sample,
// meas from encoder counts x resolution, meas = cmd with a '#' note for joints without encoder,
// joints without data left out; the CSV passes the contract checker; `feedloop log` CLI paths.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>  // popen
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "cli/log_command.hpp"
#include "recorder/recorder.hpp"
#include "recorder/trace_export.hpp"
#include "recorder_test_util.hpp"

namespace feedloop::recorder {
namespace {

using testing::ScratchDir;

// Joint x (80 steps/mm, encoder 0.49 um, 1 MHz): origin 800 steps (10 mm) at clock 0; 100 steps
// forward every 1000 ticks starting at tick 1000, then 40 back every 2000 ticks with a varying
// interval (add), encoder every 1000 ticks. Joint y: steps only. Joints z, e: nothing.
struct Fixture {
  std::vector<std::pair<int64_t, int>> x_steps;  // (clock, direction) of every x step
  std::vector<std::pair<int64_t, int64_t>> x_enc;
  std::vector<int64_t> y_steps;
};

Fixture record_fixture(Recorder& r) {
  Fixture f;
  RecordWriter& w = r.writer(Stream::servo);
  w.origin(0, 0, 800);
  const stepgen::StepRun a{1000, 0, 100, 1};
  w.step_run(0, 0, a);
  for (uint32_t k = 1; k <= 100; ++k) f.x_steps.emplace_back(stepgen::run_step_clock(0, a, k), 1);
  const int64_t p = stepgen::run_end_clock(0, a);
  const stepgen::StepRun b{2000, 7, 40, -1};
  w.step_run(0, p, b);
  for (uint32_t k = 1; k <= 40; ++k) f.x_steps.emplace_back(stepgen::run_step_clock(p, b, k), -1);
  for (int64_t c = 0; c <= 200000; c += 1000) {
    const int64_t counts = 20408 + c / 50;  // arbitrary, not the commanded position
    w.encoder_sample(0, c, counts);
    f.x_enc.emplace_back(c, counts);
  }
  const stepgen::StepRun y{3000, -5, 30, 1};
  w.step_run(1, 5000, y);
  for (uint32_t k = 1; k <= 30; ++k) f.y_steps.push_back(stepgen::run_step_clock(5000, y, k));
  return f;
}

TEST(RecorderExport, ColumnsReconstructStepsAndEncoderExactly) {
  ScratchDir dir("export");
  auto rec = Recorder::create(testing::test_options(dir.str()));
  ASSERT_TRUE(rec.ok());
  ASSERT_TRUE((*rec)->start_print("export").ok());
  const Fixture f = record_fixture(**rec);
  ASSERT_TRUE((*rec)->end_print().ok());

  auto t = build_trace(dir.logs(), ExportOptions{2000.0});
  ASSERT_TRUE(t.ok()) << t.error().to_string();
  ASSERT_EQ(t->joints, (std::vector<std::string>{"x", "y"}));
  EXPECT_DOUBLE_EQ(t->t0_s, 0.0);  // first data: the encoder sample at clock 0
  const double last_s = 200000 / 1e6;
  EXPECT_EQ(t->time_s.size(), static_cast<size_t>(std::llround(last_s * 2000.0)) + 1);
  size_t checked = 0;
  for (size_t k = 0; k < t->time_s.size(); ++k) {
    const double clock = t->time_s[k] * 1e6;
    int64_t x = 800;
    for (const auto& [c, d] : f.x_steps)
      if (static_cast<double>(c) <= clock) x += d;
    int64_t y = 0;
    for (int64_t c : f.y_steps)
      if (static_cast<double>(c) <= clock) ++y;
    ASSERT_NEAR(t->cmd_mm[0][k], static_cast<double>(x) / 80.0, 1e-12) << "row " << k;
    ASSERT_NEAR(t->cmd_mm[1][k], static_cast<double>(y) / 80.0, 1e-12) << "row " << k;
    ASSERT_EQ(t->meas_mm[1][k], t->cmd_mm[1][k]);
    // Encoder: linear between the 1 kHz samples.
    const auto i = static_cast<size_t>(clock / 1000.0);
    const double frac = clock / 1000.0 - static_cast<double>(i);
    const double counts = i + 1 < f.x_enc.size()
                              ? static_cast<double>(f.x_enc[i].second) + frac * static_cast<double>(f.x_enc[i + 1].second - f.x_enc[i].second)
                              : static_cast<double>(f.x_enc.back().second);
    ASSERT_NEAR(t->meas_mm[0][k], counts * 0.00049, 1e-9) << "row " << k;
    ++checked;
  }
  EXPECT_EQ(checked, 401u);
  // Net x: 800 + 100 - 40 steps at the end.
  EXPECT_DOUBLE_EQ(t->cmd_mm[0].back(), 860.0 / 80.0);
  bool noted = false;
  for (const std::string& c : t->comments) noted |= c.find("joint y: no encoder samples") != std::string::npos;
  EXPECT_TRUE(noted);
}

TEST(RecorderExport, CliWritesACsvThatPassesTheContractChecker) {
  ScratchDir dir("cli");
  auto rec = Recorder::create(testing::test_options(dir.str()));
  ASSERT_TRUE(rec.ok());
  ASSERT_TRUE((*rec)->start_print("cli").ok());
  record_fixture(**rec);
  ASSERT_TRUE((*rec)->end_print().ok());
  const std::string log = dir.logs().at(0);
  const std::string csv = dir.file("trace.csv");

  EXPECT_EQ(cli::log_command({"info", log}), 0);
  EXPECT_EQ(cli::log_command({"export", log, "--csv", csv, "--rate-hz", "1000"}), 0);
  std::ifstream in(csv);
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string text = ss.str();
  EXPECT_NE(text.find("# sample_rate_hz=1000\n"), std::string::npos);
  EXPECT_NE(text.find("\ntime_s,x_cmd_mm,x_meas_mm,y_cmd_mm,y_meas_mm\n"), std::string::npos);
  EXPECT_NE(text.find("# joint y: no encoder samples, y_meas_mm = y_cmd_mm"), std::string::npos);
  size_t rows = 0;
  for (char c : text) rows += c == '\n';
  EXPECT_EQ(rows, 201u + 1u + 4u);  // 201 samples, header, 4 comment lines

  // Usage errors and a bad file are exit codes with messages, not crashes.
  EXPECT_EQ(cli::log_command({}), 2);
  EXPECT_EQ(cli::log_command({"export", log}), 2);
  EXPECT_EQ(cli::log_command({"export", log, "--csv", csv, "--rate-hz", "-3"}), 2);
  EXPECT_EQ(cli::log_command({"frobnicate", log}), 2);
  EXPECT_EQ(cli::log_command({"info", dir.file("missing.flrec")}), 1);

  const std::string checker = std::string(FEEDLOOP_SHARED_DIR) + "/tools/check_contracts.py";
  if (!std::filesystem::exists(checker)) GTEST_SKIP() << "contract checker not found at " << checker;
  if (std::system("python3 --version > /dev/null 2>&1") != 0) GTEST_SKIP() << "python3 is not installed";
  const std::string cmd = "python3 '" + checker + "' trace '" + csv + "' 2>&1";
  std::string output;
  FILE* p = popen(cmd.c_str(), "r");
  ASSERT_NE(p, nullptr);
  char buf[256];
  while (std::fgets(buf, sizeof buf, p)) output += buf;
  EXPECT_EQ(pclose(p), 0) << cmd << "\n" << output;
}

TEST(RecorderExport, NothingToExportIsAClearError) {
  ScratchDir dir("empty");
  auto rec = Recorder::create(testing::test_options(dir.str()));
  ASSERT_TRUE(rec.ok());
  ASSERT_TRUE((*rec)->start_print("empty").ok());
  (*rec)->writer(Stream::io).gcode_line(1, GcodeSource::file, "G28");
  ASSERT_TRUE((*rec)->end_print().ok());
  auto t = build_trace(dir.logs(), ExportOptions{});
  ASSERT_FALSE(t.ok());
  EXPECT_NE(t.error().message.find("nothing to export"), std::string::npos);
  auto bad = build_trace(dir.logs(), ExportOptions{0.0});
  ASSERT_FALSE(bad.ok());
}

// A rate that would need terabytes (it aborted on an allocation failure) or one beyond what the
// encoders give is refused before anything is allocated; the bounds themselves are accepted.
TEST(RecorderExport, RatesOutsideTheBoundsAreRefusedNotAllocated) {
  ScratchDir dir("rates");
  auto rec = Recorder::create(testing::test_options(dir.str()));
  ASSERT_TRUE(rec.ok());
  ASSERT_TRUE((*rec)->start_print("rates").ok());
  record_fixture(**rec);
  ASSERT_TRUE((*rec)->end_print().ok());
  for (double hz : {1e12, 100001.0, 0.5, 1e-9}) {
    auto t = build_trace(dir.logs(), ExportOptions{hz});
    ASSERT_FALSE(t.ok()) << hz;
    EXPECT_NE(t.error().message.find("must be 1 Hz to 100 kHz"), std::string::npos)
        << t.error().message;
  }
  auto top = build_trace(dir.logs(), ExportOptions{kMaxExportRateHz});
  ASSERT_TRUE(top.ok()) << top.error().to_string();
  auto base = build_trace(dir.logs(), ExportOptions{1000.0});
  ASSERT_TRUE(base.ok());
  EXPECT_NEAR(static_cast<double>(top->time_s.size()),
              100.0 * static_cast<double>(base->time_s.size()), 100.0);
}

}  // namespace
}  // namespace feedloop::recorder
