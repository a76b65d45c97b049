// Issue 6 speed target: `feedloop ident fit` on a 100 s trace sampled at 1 kHz finishes in under
// 20 s on the 2-core machine. The trace is the slowest case of bench_ident (X axis with a pulley
// runout and backlash: three rounds of the search with switching effects), the command is run as
// a user runs it (CSV in, report, data files and plots out). Label slow, run serially.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>  // getpid

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "cli/ident_command.hpp"
#include "ident/excitation.hpp"
#include "ident/trace.hpp"
#include "sim/experiments/gantry_recording.hpp"

namespace feedloop::ident {
namespace {

double cpu_s() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

TEST(IdentSpeed, FitOf100sTraceAt1kHzUnder20s) {
  const auto dir = std::filesystem::temp_directory_path() / ("feedloop_ident_speed_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  sim::GantryAxisParams p = sim::thesis_x_axis();
  p.belt_span_mm = 1e6;
  p.effects.periodic_position = {true, 33.93, 15.0};
  p.effects.backlash = {true, 30.0};
  RandomMovesOptions ro;
  ro.duration_s = 100.0;
  auto tr = sim::record_gantry_trace(p, random_moves(ro), 1000.0, "x");
  ASSERT_TRUE(tr.ok()) << tr.error().to_string();
  ASSERT_EQ(tr.value().samples(), 100000u);
  const auto trace = dir / "trace.csv";
  ASSERT_TRUE(write_trace_csv(trace.string(), tr.value()).ok());

  const double c0 = cpu_s();
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_EQ(cli::ident_command({"fit", "--trace", trace.string(), "--out", (dir / "out").string()}), 0);
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double cpu = cpu_s() - c0;
  std::printf("ident fit, 100 s at 1 kHz (X, periodic_position + backlash): %.2f s wall, %.2f s CPU (2 threads)\n",
              wall_s, cpu);
  std::ifstream f(dir / "out" / "report.json");
  std::stringstream json;
  json << f.rdbuf();
  EXPECT_NE(json.str().find("periodic_position"), std::string::npos) << json.str();
  EXPECT_NE(json.str().find("backlash"), std::string::npos) << json.str();
  EXPECT_LT(wall_s, 20.0);
  // The work itself, whatever else runs on the machine: under 10 s of CPU on both threads.
  EXPECT_LT(cpu, 10.0);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace feedloop::ident
