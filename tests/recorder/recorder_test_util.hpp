// Helpers shared by the recorder tests and benchmark: scratch directories, recorder options,
// realistic step streams (trapezoid moves through the real step generator and compressor).
#pragma once

#include <unistd.h>  // getpid

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <string>
#include <vector>

#include "core/joint_segment.hpp"
#include "drivers/stepgen/step_compressor.hpp"
#include "drivers/stepgen/step_generator.hpp"
#include "recorder/recorder.hpp"

namespace feedloop::recorder::testing {

// A fresh directory under the system temp dir, removed on destruction.
class ScratchDir {
 public:
  explicit ScratchDir(const std::string& tag) {
    static std::atomic<int> counter{0};
    path_ = std::filesystem::temp_directory_path() /
            ("feedloop_rec_" + tag + "_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  std::string str() const { return path_.string(); }
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  std::vector<std::string> logs() const {
    std::vector<std::string> out;
    for (const auto& e : std::filesystem::directory_iterator(path_))
      if (e.path().extension() == ".flrec") out.push_back(e.path().string());
    std::sort(out.begin(), out.end());
    return out;
  }

 private:
  std::filesystem::path path_;
};

inline std::vector<JointInfo> test_joints() {
  return {{"x", 80.0, 0.00049, 1'000'000},
          {"y", 80.0, 0.0, 1'000'000},
          {"z", 400.0, 0.0, 1'000'000},
          {"e", 415.0, 0.0, 1'000'000}};
}

inline RecorderOptions test_options(const std::string& dir) {
  RecorderOptions o;
  o.config.enabled = true;
  o.config.directory = dir;
  o.config.max_file_size_mb = 64.0;
  o.config.keep_files = 0;
  o.config_yaml = "name: recorder test\naxes: [x, y, z, e]\n";
  o.joints = test_joints();
  o.io_ring_bytes = 1 << 16;
  o.planner_ring_bytes = 1 << 16;
  o.servo_ring_bytes = 1 << 20;
  return o;
}

struct RunItem {
  int64_t start_clock;
  stepgen::StepRun run;
};

struct CollectRuns final : stepgen::RunSink {
  std::vector<RunItem> runs;
  void on_run(int64_t start_clock, const stepgen::StepRun& run) override { runs.push_back({start_clock, run}); }
};

// Back-and-forth trapezoid moves of one joint (accel 3000 mm/s^2, cruise 100 mm/s, 20 mm), as
// the engine would step them: exact step times -> compressed runs (5 us error at `clock_hz`).
inline std::vector<RunItem> trapezoid_runs(int moves, double steps_per_mm, double clock_hz) {
  CollectRuns sink;
  stepgen::StepCompressor comp;
  comp.configure(stepgen::StepCompressorParams{5e-6 * clock_hz, 65535}, &sink);
  comp.reset(0, 0.0);
  stepgen::StepGenerator gen;
  gen.configure(steps_per_mm, stepgen::TickMap{0.0, clock_hz}, &comp);
  gen.set_position_mm(0.0);
  const double a = 3000.0, v = 100.0, d = 20.0;
  const double ta = v / a, da = 0.5 * a * ta * ta, tc = (d - 2 * da) / v;
  double t = 0.01, x = 0.0;
  for (int m = 0; m < moves; ++m) {
    const double dir = (m % 2 == 0) ? 1.0 : -1.0;
    JointSegment s1{t, ta, x, 0.0, dir * 0.5 * a, 0.0};
    JointSegment s2{t + ta, tc, x + dir * da, dir * v, 0.0, 0.0};
    JointSegment s3{t + ta + tc, ta, x + dir * (d - da), dir * v, -dir * 0.5 * a, 0.0};
    gen.add_segment(s1);
    gen.add_segment(s2);
    gen.add_segment(s3);
    t += 2 * ta + tc + 0.005;
    x += dir * d;
  }
  gen.flush();
  comp.flush();
  return sink.runs;
}

}  // namespace feedloop::recorder::testing
