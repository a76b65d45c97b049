// Step generation + compression throughput and bytes on the wire per step.
// Usage: bench_stepgen [--json FILE] [--moves N] [--gcode FILE [--config FILE]]
// Workloads: printing-like trapezoid moves (quadratic pieces) and 1 ms cubic pieces (delta-like);
// with --gcode, also every joint of a real slicer file as batch mode plans it (its joint segments,
// its steps/mm and MCU clock), one row per joint and error bound.
// Columns: workload, error bound, steps, ns/step for generation alone, ns/step for
// generation+compression+batch encoding, Msteps/s, run bytes per step, wire bytes per step
// (including frame and message headers, docs/protocol.md), mean steps per run.
#include <time.h>  // clock_gettime

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench/bench_json.hpp"
#include "config/config.hpp"
#include "drivers/stepgen/step_batcher.hpp"
#include "drivers/stepgen/step_compressor.hpp"
#include "drivers/stepgen/step_generator.hpp"
#include "engine/batch.hpp"
#include "engine/config_mapping.hpp"
#include "segment_streams.hpp"

using namespace feedloop;
using namespace feedloop::stepgen;

namespace {

// Keeps the exact step times, so that compression can be timed alone on them.
struct StoreSteps final : StepSink {
  std::vector<double> ticks;
  std::vector<int8_t> dirs;
  void on_steps(const double* t, const int8_t* d, size_t n) override {
    ticks.insert(ticks.end(), t, t + n);
    dirs.insert(dirs.end(), d, d + n);
  }
};
struct CountBatches final : BatchSink {
  uint64_t bytes = 0, batches = 0;
  void on_batch(const StepBatch& b) override { bytes += b.body_bytes; ++batches; }
};

// Per QUEUE_STEPS frame: frame header 5 + CRC 2 + message type 1 + axis 1 (docs/protocol.md).
constexpr double kFrameOverheadBytes = 9.0;

struct Row {
  std::string workload;
  double err_us, steps, gen_ns, comp_ns, total_ns, msteps_s, run_bps, wire_bps, steps_per_run;
  double searches_per_step, trials_per_search, scanned_per_step;
};

// Thread CPU time: robust against other processes on a shared machine (this is single-threaded
// work, so CPU time is what one core spends on it).
double now_s() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// Compresses stored step times in the chunks the generator hands over (StepGenerator::kChunk).
void compress(const StoreSteps& st, StepCompressor& c) {
  constexpr size_t kChunk = 256;
  for (size_t i = 0; i < st.ticks.size(); i += kChunk)
    c.on_steps(st.ticks.data() + i, st.dirs.data() + i, std::min(kChunk, st.ticks.size() - i));
}

Row run(const std::string& name, const std::vector<JointSegment>& segs, double spm, double err_us,
        double clock_hz = 20e6) {
  const TickMap map{0.0, clock_hz};
  Row r{name, err_us, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
  StoreSteps st;
  {
    // Generation alone (into a vector reserved beforehand: the stores are part of the cost).
    StoreSteps warm;
    StepGenerator g;
    g.configure(spm, map, &warm);
    g.set_position_mm(segs.front().c0_mm);
    for (const auto& s : segs) g.add_segment(s);
    g.flush();
    // Touched before the timing: on a virtual machine the first touch of a page can cost more
    // than generating the steps it holds (20 ns per 8 bytes measured on one).
    st.ticks.assign(warm.ticks.size(), 0.0);
    st.dirs.assign(warm.dirs.size(), 0);
    st.ticks.clear();
    st.dirs.clear();
    g.configure(spm, map, &st);
    g.set_position_mm(segs.front().c0_mm);
    const double t0 = now_s();
    for (const auto& s : segs) g.add_segment(s);
    g.flush();
    r.gen_ns = (now_s() - t0) * 1e9 / static_cast<double>(st.ticks.size());
    r.steps = static_cast<double>(st.ticks.size());
  }
  {
    // Compression and batch encoding alone, on the stored times, read once before the timing
    // (on a virtual machine the first read of freshly written memory cost 6-10 ns per step, as
    // much as the compression: measured on one).
    volatile double sink = 0.0;
    for (size_t i = 0; i < st.ticks.size(); i += 512 / sizeof(double)) sink = sink + st.ticks[i];
    for (size_t i = 0; i < st.dirs.size(); i += 512) sink = sink + st.dirs[i];
    CountBatches cb;
    StepBatcher b;
    b.configure(0, 200, &cb);
    StepCompressor c;
    c.configure({err_us * clock_hz * 1e-6, 65535}, &b);
    const double t0 = now_s();
    compress(st, c);
    c.flush();
    b.flush();
    r.comp_ns = (now_s() - t0) * 1e9 / r.steps;
  }
  // The whole path as the pipeline runs it: generation straight into compression.
  CountBatches cb;
  StepBatcher b;
  b.configure(0, 200, &cb);
  StepCompressor c;
  c.configure({err_us * clock_hz * 1e-6, 65535}, &b);
  StepGenerator g;
  g.configure(spm, map, &c);
  g.set_position_mm(segs.front().c0_mm);
  const double t0 = now_s();
  for (const auto& s : segs) g.add_segment(s);
  g.flush();
  c.flush();
  b.flush();
  const double dt = now_s() - t0;
  r.total_ns = dt * 1e9 / r.steps;
  r.msteps_s = r.steps / dt / 1e6;
  r.run_bps = cb.bytes / r.steps;
  r.wire_bps = (cb.bytes + kFrameOverheadBytes * cb.batches) / r.steps;
  r.steps_per_run = r.steps / static_cast<double>(c.stats().runs);
  r.searches_per_step = static_cast<double>(c.stats().searches) / r.steps;
  r.scanned_per_step = static_cast<double>(c.stats().scanned) / r.steps;
  r.trials_per_search = static_cast<double>(c.stats().trials) /
                        std::max<double>(1.0, static_cast<double>(c.stats().searches));
  return r;
}

// Every joint's segments of a G-code file as batch mode plans them (one thread, no stepping).
struct SegmentLog final : planner::JointSink {
  std::array<std::vector<JointSegment>, engine::kJoints> joints;
  void on_joint_segment(int joint, const JointSegment& s) override {
    joints[static_cast<size_t>(joint)].push_back(s);
  }
};

// Appends one row per joint that moves and error bound; false (with a message) on a bad file.
bool gcode_rows(const std::string& gcode, const std::string& config_path, std::vector<Row>& rows) {
  auto cfg = config_path.empty() ? Result<config::MachineConfig>(config::default_config())
                                 : config::load_config_file(config_path);
  if (!cfg) {
    std::fprintf(stderr, "%s\n", cfg.error().to_string().c_str());
    return false;
  }
  SegmentLog log;
  engine::BatchOptions opt;
  opt.threads = 1;
  opt.last_stage = engine::BatchStage::step_times;  // the joints' segments reach the tap
  opt.segment_tap = &log;
  auto sum = engine::run_batch(gcode, cfg.value(), opt);
  if (!sum) {
    std::fprintf(stderr, "%s\n", sum.error().to_string().c_str());
    return false;
  }
  const auto spm = engine::steps_per_mm(cfg.value());
  const auto clock_hz = static_cast<double>(cfg.value().stepgen.mcu_clock_hz);
  const std::string base = std::filesystem::path(gcode).stem().string();
  for (double e : {5.0, 25.0})
    for (size_t j = 0; j < engine::kJoints; ++j)
      if (!log.joints[j].empty())
        rows.push_back(
            run(base + ":" + sum.value().joint_names[j], log.joints[j], spm[j], e, clock_hz));
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  std::string json, gcode, config_path;
  int moves = 20000;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--json") && i + 1 < argc) json = argv[++i];
    else if (!std::strcmp(argv[i], "--moves") && i + 1 < argc) moves = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--gcode") && i + 1 < argc)
      gcode = argv[++i];
    else if (!std::strcmp(argv[i], "--config") && i + 1 < argc)
      config_path = argv[++i];
    else {
      std::fprintf(stderr, "usage: %s [--json FILE] [--moves N] [--gcode FILE [--config FILE]]\n",
                   argv[0]);
      return 2;
    }
  }
  std::mt19937_64 rng(42);
  const auto trap = testing::trapezoid_stream(rng, moves);
  const auto cubic = testing::cubic_stream(rng, moves * 5);
  std::vector<Row> rows;
  for (double e : {5.0, 25.0}) {
    rows.push_back(run("trapezoid", trap, 80.0, e));
    rows.push_back(run("cubic_1ms", cubic, 160.0, e));
  }
  if (!gcode.empty() && !gcode_rows(gcode, config_path, rows)) return 1;
  std::printf("%-20s %6s %10s %8s %8s %10s %9s %8s %8s %9s %10s %9s %9s %8s\n", "workload",
              "err_us", "steps", "gen_ns", "comp_ns", "comp_Mst/s", "total_ns", "Msteps/s",
              "run_B/st", "wire_B/st", "steps/run", "search/st", "trial/sr", "scan/st");
  for (const auto& r : rows)
    std::printf(
        "%-20s %6.0f %10.0f %8.2f %8.2f %10.1f %9.2f %8.1f %8.3f %9.3f %10.1f %9.3f %9.2f %8.2f\n",
        r.workload.c_str(), r.err_us, r.steps, r.gen_ns, r.comp_ns, 1e3 / r.comp_ns, r.total_ns,
        r.msteps_s, r.run_bps, r.wire_bps, r.steps_per_run, r.searches_per_step,
        r.trials_per_search, r.scanned_per_step);
  if (!json.empty()) {
    nlohmann::json out = {{"benchmark", "stepgen"}, {"rows", nlohmann::json::array()}};
    for (const auto& r : rows)
      out["rows"].push_back({{"workload", r.workload},
                             {"max_error_us", r.err_us},
                             {"steps", static_cast<int64_t>(r.steps)},
                             {"gen_ns_per_step", r.gen_ns},
                             {"compress_ns_per_step", r.comp_ns},
                             {"total_ns_per_step", r.total_ns},
                             {"msteps_per_s", r.msteps_s},
                             {"run_bytes_per_step", r.run_bps},
                             {"wire_bytes_per_step", r.wire_bps},
                             {"steps_per_run", r.steps_per_run}});
    if (!feedloop::bench::write_json(json, out)) return 1;
  }
  return 0;
}
