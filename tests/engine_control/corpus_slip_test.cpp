// Issue 13 item 6, "a default printer that does not slip": every file of the public G-code corpus
// (../shared/gcode) printed in virtual time on the simulated printer of its config (Cartesian
// files on the embedded default, `*delta*` files on config/examples/delta_sim.yaml), through the
// daemon's pipeline (engine::run_simulated, what `feedloop batch FILE --simulate` runs): no
// lost-step event, no step lost by the simulated motors, no fault, no rejected line, and a
// tracking error a working closed loop has. Labels `slow` and `long` (about 15 min of CPU for the
// corpus; not in scripts/test.sh: `ctest --test-dir build -L long`);
// FEEDLOOP_CORPUS_FILTER=substring runs only the matching files. bench/corpus runs the same files
// through feedloopd as well and prints the table.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "config/config.hpp"
#include "engine/sim_run.hpp"

namespace feedloop::engine {
namespace {

namespace fs = std::filesystem;

TEST(CorpusSlip, EveryCorpusFileRunsWithoutALostStepOrAFault) {
  const fs::path dir = fs::path(FEEDLOOP_SHARED_DIR) / "gcode";
  if (!fs::is_directory(dir)) GTEST_SKIP() << "G-code corpus absent: " << dir.string();
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == ".gcode") files.push_back(e.path());
  if (const char* only = std::getenv("FEEDLOOP_CORPUS_FILTER"))
    std::erase_if(files, [only](const fs::path& p) { return p.filename().string().find(only) == std::string::npos; });
  std::sort(files.begin(), files.end());
  ASSERT_FALSE(files.empty());
  auto delta = config::load_config_file(std::string(FEEDLOOP_SOURCE_DIR) + "/config/examples/delta_sim.yaml");
  ASSERT_TRUE(delta.ok()) << delta.error().to_string();
  for (const fs::path& f : files) {
    SCOPED_TRACE(f.filename().string());
    const bool is_delta = f.filename().string().find("delta") != std::string::npos;
    const config::MachineConfig& cfg = is_delta ? *delta : config::default_config();
    std::vector<std::string> lines;
    std::ifstream in(f);
    for (std::string l; std::getline(in, l);) lines.push_back(l);
    SimRunOptions o;
    o.keep_samples = false;
    o.timeout_s = 1e5;
    const auto t0 = std::chrono::steady_clock::now();
    auto r = run_simulated(cfg, lines, o);
    ASSERT_TRUE(r.ok()) << r.error().to_string();
    int64_t lost_full_steps = 0;
    for (int64_t n : r->lost_full_steps) lost_full_steps += n;
    std::printf("%-42s %7zu lines  %llu rejected  %llu lost-step events  plant lost %lld full steps  "
                "%llu faults  e_t mean %.4f max %.4f mm  print %.0f s  (%.0f s wall)\n",
                f.filename().string().c_str(), lines.size(), static_cast<unsigned long long>(r->rejected),
                static_cast<unsigned long long>(r->lost_step_events), static_cast<long long>(lost_full_steps),
                static_cast<unsigned long long>(r->faults), r->tracking_error_mean_mm, r->tracking_error_max_mm,
                r->motion_time_s,
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    EXPECT_EQ(r->error, "");
    EXPECT_EQ(r->rejected, 0u);
    EXPECT_EQ(r->lost_step_events, 0u);
    EXPECT_EQ(lost_full_steps, 0);
    EXPECT_EQ(r->faults, 0u);
    EXPECT_EQ(r->commands, lines.size());
    // The whole file ran: the slicer's estimate (M73 R at the start) is 13-58 min; e_t sampled at
    // the encoders' reports throughout.
    EXPECT_GT(r->motion_time_s, 600.0);
    EXPECT_GT(r->tracking_error_samples, static_cast<uint64_t>(r->motion_time_s * 100.0));
    EXPECT_GT(r->tracking_error_mean_mm, 0.0);
    EXPECT_LT(r->tracking_error_mean_mm, 0.3);
    EXPECT_LT(r->tracking_error_max_mm, 2.0);  // the device loops' following-error trip
    for (int j = 0; j < 3; ++j) {
      const DeviceLoopTelemetry& t = r->device_loops[static_cast<size_t>(j)];
      if (!t.enabled) continue;
      EXPECT_EQ(t.slips, 0u) << "joint " << j;
      EXPECT_EQ(t.deadline_misses, 0u) << "joint " << j;
      EXPECT_GT(t.reports, static_cast<uint64_t>(r->motion_time_s * 90.0)) << "joint " << j;
    }
  }
}

}  // namespace
}  // namespace feedloop::engine
