// Test support for batch mode: small generated G-code programs (so the tests run without the
// corpus), a per-axis hash of the QUEUE_STEPS bodies, and a run through the StepChecker.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "config/config.hpp"
#include "engine/batch.hpp"
#include "tests/engine/step_check.hpp"

namespace feedloop::engine::testing {

// Writes text to a fresh file in the test temp directory and returns its path.
inline std::string write_temp(const std::string& name, const std::string& text) {
  const auto path = std::filesystem::temp_directory_path() / ("feedloop_engine_" + name);
  std::ofstream(path) << text;
  return path.string();
}

// A printing-like program: a spiral of short extruding moves around (cx, cy) with changing feed
// rates, some retractions and travel moves, layer changes. max_r_mm keeps a delta inside its disc.
inline std::string spiral_gcode(double cx, double cy, double max_r_mm, int moves) {
  std::string g = "G21\nG90\nM83\nG28\nG1 Z0.3 F1200\n";  // homed first, as a slicer's start block
  char line[160];
  double z = 0.3;
  for (int i = 0; i < moves; ++i) {
    const double a = 0.37 * i, r = max_r_mm * (0.2 + 0.8 * std::fmod(i * 0.013, 1.0));
    const double x = cx + r * std::cos(a), y = cy + r * std::sin(a);
    const int feed = 1200 + (i * 977) % 7800;
    if (i % 97 == 96) {
      std::snprintf(line, sizeof line, "G1 E-0.8 F2400\nG0 X%.3f Y%.3f F9000\nG1 E0.8 F2400\n", x, y);
    } else {
      std::snprintf(line, sizeof line, "G1 X%.3f Y%.3f E%.4f F%d\n", x, y, 0.02 + 0.001 * (i % 13), feed);
    }
    g += line;
    if (i % 400 == 399) {
      z += 0.2;
      std::snprintf(line, sizeof line, "G1 Z%.2f F600\n", z);
      g += line;
    }
  }
  return g;
}

// FNV-1a over every batch (first clock + body) of each axis: equal hashes = identical streams.
class BatchHasher final : public stepgen::BatchSink {
 public:
  void on_batch(const stepgen::StepBatch& b) override {
    uint64_t& h = hash_[b.axis];
    auto mix = [&h](uint8_t byte) { h = (h ^ byte) * 1099511628211ull; };
    for (int i = 0; i < 8; ++i) mix(static_cast<uint8_t>(static_cast<uint64_t>(b.first_clock) >> (8 * i)));
    for (size_t i = 0; i < b.body_bytes; ++i) mix(b.body[i]);
  }
  uint64_t hash(int axis) const { return hash_[static_cast<size_t>(axis)]; }

 private:
  std::array<uint64_t, kJoints> hash_{14695981039346656037ull, 14695981039346656037ull,
                                      14695981039346656037ull, 14695981039346656037ull};
};

struct CheckedRun {
  BatchSummary summary;
  std::array<JointCheckResult, kJoints> joints{};
  double max_error_us = 0.0;
  uint64_t not_found = 0;
};

// run_batch with the StepChecker on both taps.
inline Result<CheckedRun> run_checked(const std::string& path, const config::MachineConfig& cfg, int threads = 2) {
  StepChecker checker(steps_per_mm(cfg), static_cast<double>(cfg.stepgen.mcu_clock_hz), cfg.stepgen.max_step_error_us);
  BatchOptions opt;
  opt.threads = threads;
  opt.segment_tap = &checker;
  opt.batch_tap = &checker;
  auto sum = run_batch(path, cfg, opt);
  if (!sum) return sum.error();
  CheckedRun r;
  r.summary = *sum;
  for (int j = 0; j < kJoints; ++j) {
    r.joints[static_cast<size_t>(j)] = checker.result(j);
    r.max_error_us = std::max(r.max_error_us, r.joints[static_cast<size_t>(j)].max_error_us);
    r.not_found += r.joints[static_cast<size_t>(j)].not_found;
  }
  return r;
}

inline config::MachineConfig delta_config() {
  auto c = config::load_config_file(std::string(FEEDLOOP_SOURCE_DIR) + "/config/examples/delta_sim.yaml");
  return c ? *c : config::MachineConfig{};
}

}  // namespace feedloop::engine::testing
