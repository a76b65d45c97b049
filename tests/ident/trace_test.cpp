// Trace CSV v1: round trip, located errors, and recording an excitation on the simulator.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "ident/excitation.hpp"
#include "ident/trace.hpp"
#include "sim/experiments/gantry_recording.hpp"

namespace feedloop::ident {
namespace {

TEST(TraceCsv, RoundTripKeepsMetadataAxesAndValues) {
  Trace t;
  t.metadata = {{"sample_rate_hz", "1000"}, {"source", "test"}};
  t.time_s = {0.0, 0.001, 0.002};
  t.axes.push_back(AxisTrace{"x", {0.0, 0.0106, 0.0212}, {0.0, 0.00049, 0.0098}});
  t.axes.push_back(AxisTrace{"y", {1.0, 2.0, 3.0}, {-1.0, -2.0, -3.5}});
  auto back = parse_trace_csv(format_trace_csv(t), "mem");
  ASSERT_TRUE(back.ok()) << back.error().to_string();
  const Trace& r = back.value();
  ASSERT_EQ(r.axes.size(), 2u);
  EXPECT_EQ(r.axes[1].name, "y");
  EXPECT_EQ(r.metadata[0].first, "sample_rate_hz");
  EXPECT_EQ(r.metadata[0].second, "1000");
  EXPECT_NEAR(r.axes[0].cmd_mm[2], 0.0212, 1e-9);
  EXPECT_NEAR(r.axes[1].meas_mm[2], -3.5, 1e-9);
  EXPECT_NEAR(r.period_s(), 0.001, 1e-12);
}

TEST(TraceCsv, ExtraColumnsAreIgnoredAndOrderIsFree) {
  auto r = parse_trace_csv("time_s,x_meas_mm,note,x_cmd_mm\n0,1,a,2\n0.5,3,b,4\n", "mem");
  ASSERT_TRUE(r.ok()) << r.error().to_string();
  ASSERT_EQ(r.value().axes.size(), 1u);
  EXPECT_EQ(r.value().axes[0].cmd_mm[1], 4.0);
  EXPECT_EQ(r.value().axes[0].meas_mm[1], 3.0);
}

TEST(TraceCsv, ErrorsAreLocated) {
  auto bad_number = parse_trace_csv("# a=b\ntime_s,x_cmd_mm,x_meas_mm\n0,0,0\n0.001,0.1,zz\n", "f.csv");
  ASSERT_FALSE(bad_number.ok());
  EXPECT_EQ(bad_number.error().where.source, "f.csv");
  EXPECT_EQ(bad_number.error().where.line, 4);
  EXPECT_EQ(bad_number.error().where.column, 11);
  auto not_increasing = parse_trace_csv("time_s,x_cmd_mm,x_meas_mm\n0,0,0\n0,0.1,0\n", "f.csv");
  ASSERT_FALSE(not_increasing.ok());
  EXPECT_EQ(not_increasing.error().where.line, 3);
  auto no_meas = parse_trace_csv("time_s,x_cmd_mm\n0,0\n", "f.csv");
  ASSERT_FALSE(no_meas.ok());
  EXPECT_EQ(no_meas.error().where.line, 1);
  EXPECT_EQ(no_meas.error().where.column, 8);
  auto short_row = parse_trace_csv("time_s,x_cmd_mm,x_meas_mm\n0,0\n", "f.csv");
  ASSERT_FALSE(short_row.ok());
  EXPECT_EQ(short_row.error().where.line, 2);
  EXPECT_FALSE(read_trace_csv("no/such/file.csv").ok());
}

// A CSV of `rows` samples of cmd = 2 t, meas = 3 t at the given times (lines from 2).
std::string linear_trace_csv(const std::vector<double>& times) {
  std::string csv = "time_s,x_cmd_mm,x_meas_mm\n";
  char buf[96];
  for (double t : times) {
    std::snprintf(buf, sizeof buf, "%.6f,%.7f,%.7f\n", t, 2.0 * t, 3.0 * t);
    csv += buf;
  }
  return csv;
}

// A path that never ends is refused at the bound (it was read until memory ran out).
TEST(TraceCsv, AFileBeyondTheBoundIsRefused) {
  auto r = read_trace_csv("/dev/zero");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().where.source, "/dev/zero");
  EXPECT_NE(r.error().message.find("larger than 256 MiB"), std::string::npos) << r.error().message;
}

TEST(TraceCsv, AnEvenTraceIsKeptAsItIs) {
  std::vector<double> times;
  for (int k = 0; k < 500; ++k) times.push_back(0.001 * k);
  auto r = parse_trace_csv(linear_trace_csv(times), "even.csv");
  ASSERT_TRUE(r.ok());
  std::string note = "stale";
  auto e = evenly_sampled(r.value(), "even.csv", &note);
  ASSERT_TRUE(e.ok());
  EXPECT_TRUE(note.empty());
  EXPECT_EQ(e.value().time_s, r.value().time_s);
  EXPECT_EQ(e.value().axes[0].meas_mm, r.value().axes[0].meas_mm);
}

TEST(TraceCsv, AJitteredTraceIsResampledOntoItsMedianStep) {
  // Steps alternate 0.8 and 1.2 ms around a median of 1.0 (every third is 1.0 ms).
  std::vector<double> times{0.0};
  for (int k = 1; k < 900; ++k)
    times.push_back(times.back() + (k % 3 == 0 ? 1.0e-3 : k % 3 == 1 ? 0.8e-3 : 1.2e-3));
  auto r = parse_trace_csv(linear_trace_csv(times), "jitter.csv");
  ASSERT_TRUE(r.ok());
  std::string note;
  auto e = evenly_sampled(r.value(), "jitter.csv", &note);
  ASSERT_TRUE(e.ok());
  EXPECT_NE(note.find("resampled"), std::string::npos);
  const Trace& t = e.value();
  ASSERT_EQ(t.axes.size(), 1U);
  ASSERT_EQ(t.time_s.size(), t.axes[0].cmd_mm.size());
  EXPECT_NEAR(t.period_s(), 1.0e-3, 1e-9);
  EXPECT_EQ(t.time_s.size(), static_cast<size_t>(std::floor(times.back() / 1.0e-3 + 1e-9)) + 1);
  // Linear columns stay exact under linear interpolation (up to the CSV's 7 decimals).
  for (size_t k = 0; k < t.time_s.size(); k += 37) {
    EXPECT_NEAR(t.axes[0].cmd_mm[k], 2.0 * t.time_s[k], 2e-7) << k;
    EXPECT_NEAR(t.axes[0].meas_mm[k], 3.0 * t.time_s[k], 2e-7) << k;
  }
}

TEST(TraceCsv, MissingRowsAreAnErrorAtTheRowAfterTheGap) {
  std::vector<double> times;
  for (int k = 0; k < 300; ++k)
    if (k < 100 || k >= 104) times.push_back(0.001 * k);  // rows 100-103 lost
  auto r = parse_trace_csv("# sample_rate_hz=1000\n" + linear_trace_csv(times), "gap.csv");
  ASSERT_TRUE(r.ok());
  auto e = evenly_sampled(r.value(), "gap.csv");
  ASSERT_FALSE(e.ok());
  EXPECT_EQ(e.error().where.source, "gap.csv");
  EXPECT_EQ(e.error().where.line, 103);  // metadata, header, rows 0-99 on lines 3-102, then k = 104
  EXPECT_NE(e.error().message.find("5.0 times"), std::string::npos) << e.error().message;
}

TEST(Excitation, RandomMovesStayNearTheDriftAndRecordFollowsTheCommand) {
  RandomMovesOptions o;
  o.duration_s = 4.0;
  o.travel_mm = 10.0;
  const auto u = random_moves(o);
  ASSERT_EQ(u.size(), 4000u);
  int moves = 0;
  double max_jump = 0.0;
  for (size_t k = 1; k < u.size(); ++k) {
    const double jump = std::abs(u[k] - u[k - 1]) - 10.0 * 2.0 / 4000.0;
    if (jump > 1e-3) ++moves;
    max_jump = std::max(max_jump, std::abs(u[k] - u[k - 1]));
  }
  EXPECT_GT(moves, 4.0 / 0.15);
  EXPECT_LT(max_jump, o.step_max_mm + 0.01);
  auto trace = sim::record_gantry_trace(sim::thesis_x_axis(), u, 1000.0, "x");
  ASSERT_TRUE(trace.ok()) << trace.error().to_string();
  const AxisTrace& a = trace.value().axes[0];
  // The carriage follows the command within a fraction of a mm and the step quantisation holds.
  double max_err = 0.0;
  for (size_t k = 0; k < u.size(); ++k) {
    max_err = std::max(max_err, std::abs(a.meas_mm[k] - a.cmd_mm[k]));
    EXPECT_LT(std::abs(a.cmd_mm[k] - u[k]), 0.0106);
  }
  EXPECT_LT(max_err, 0.2);  // a 0.08 mm instantaneous move overshoots
  EXPECT_GT(max_err, 0.001);
}

}  // namespace
}  // namespace feedloop::ident
