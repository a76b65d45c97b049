// Batch mode over the G-code corpus: throughput, bytes on the wire per step, peak memory, CPU and
// wall time, and Klipper's published batch-mode figures for comparison (ANCHORS.md).
// Usage: bench_batch [--json FILE] [--gcode-dir DIR] [--reps N]
//
// Every measurement runs in its own child process (fork), so the peak RSS of one file
// (getrusage(RUSAGE_SELF).ru_maxrss in the child) does not include another's. The 45 MB
// 12-benchy file is decompressed (xz -dk) into a temporary directory and removed afterwards.
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "config/config.hpp"
#include "engine/batch.hpp"

namespace fs = std::filesystem;
using namespace feedloop;

namespace {

struct Run {
  bool ok = false;
  int64_t lines = 0;
  uint64_t moves = 0, steps = 0, wire_bytes = 0, check_failures = 0;
  double wall_s = 0, cpu_s = 0, max_rss_mb = 0, bytes_per_step = 0;
};

// Runs batch mode on one file in a child process and reads its figures back through a pipe.
Run run_child(const std::string& file, const config::MachineConfig& cfg, int threads) {
  int fds[2];
  if (pipe(fds) != 0) return {};
  const pid_t pid = fork();
  if (pid < 0) return {};
  if (pid == 0) {
    close(fds[0]);
    Run r;
    engine::BatchOptions opt;
    opt.threads = threads;
    auto sum = engine::run_batch(file, cfg, opt);
    if (sum) {
      r.ok = true;
      r.lines = sum->lines;
      r.moves = sum->moves;
      r.steps = sum->total_steps;
      r.wire_bytes = sum->wire_bytes;
      r.check_failures = sum->check_failures;
      r.wall_s = sum->wall_s;
      r.cpu_s = sum->cpu_s;
      r.bytes_per_step = sum->wire_bytes_per_step;
    }
    rusage ru{};
    getrusage(RUSAGE_SELF, &ru);
    r.max_rss_mb = static_cast<double>(ru.ru_maxrss) / 1024.0;  // ru_maxrss is in KiB on Linux
    const ssize_t w = write(fds[1], &r, sizeof r);
    _exit(w == static_cast<ssize_t>(sizeof r) ? 0 : 1);
  }
  close(fds[1]);
  Run r;
  const ssize_t got = read(fds[0], &r, sizeof r);
  close(fds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  if (got != static_cast<ssize_t>(sizeof r)) return {};
  return r;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

struct Job {
  std::string name, path;
  bool delta = false;
};

}  // namespace

int main(int argc, char** argv) {
  std::string json_path, dir = std::string(FEEDLOOP_SHARED_DIR) + "/gcode";
  int reps = 3;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--json") && i + 1 < argc) json_path = argv[++i];
    else if (!std::strcmp(argv[i], "--gcode-dir") && i + 1 < argc) dir = argv[++i];
    else if (!std::strcmp(argv[i], "--reps") && i + 1 < argc) reps = std::max(1, std::atoi(argv[++i]));
    else {
      std::fprintf(stderr, "usage: %s [--json FILE] [--gcode-dir DIR] [--reps N]\n", argv[0]);
      return 2;
    }
  }
  if (!fs::is_directory(dir)) {
    std::fprintf(stderr, "bench_batch: no G-code corpus at %s (use --gcode-dir)\n", dir.c_str());
    return 1;
  }
  const config::MachineConfig cart = config::default_config();
  auto delta_cfg = config::load_config_file(std::string(FEEDLOOP_SOURCE_DIR) + "/config/examples/delta_sim.yaml");
  if (!delta_cfg) {
    std::fprintf(stderr, "bench_batch: %s\n", delta_cfg.error().to_string().c_str());
    return 1;
  }

  std::vector<Job> jobs;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().extension() != ".gcode") continue;
    const std::string name = e.path().stem().string();
    jobs.push_back({name, e.path().string(), name.find("delta") != std::string::npos});
  }
  std::sort(jobs.begin(), jobs.end(), [](const Job& a, const Job& b) { return a.name < b.name; });
  // The 12-benchy plate, decompressed for the run.
  std::string tmp_dir;
  const fs::path xz = fs::path(dir) / "benchy_x12_cartesian_LARGE.gcode.xz";
  if (fs::exists(xz)) {
    char tmpl[] = "/tmp/bench_batch_XXXXXX";
    if (mkdtemp(tmpl) != nullptr) {
      tmp_dir = tmpl;
      const std::string out = tmp_dir + "/benchy_x12_cartesian_LARGE.gcode";
      const std::string cmd = "xz -dc '" + xz.string() + "' > '" + out + "'";
      if (std::system(cmd.c_str()) == 0) jobs.push_back({"benchy_x12_cartesian_LARGE", out, false});
      else std::fprintf(stderr, "bench_batch: xz failed; skipping the 12-benchy file\n");
    }
  }

  nlohmann::json out;
  out["files"] = nlohmann::json::array();
  std::printf("batch mode, %d rep(s) per file (median; CPU = all threads of the process)\n", reps);
  std::printf("%-36s %8s %8s %9s %10s %9s %8s %8s %8s %7s %7s %6s\n", "file", "lines", "klines/s",
              "kmoves/s", "Msteps/s", "steps", "B/st@5", "B/st@25", "peakMB", "cpu_s", "wall_s", "fails");
  double benchy_wall = 0, benchy_cpu = 0, cube_mb = 0, large_mb = 0;
  for (const Job& job : jobs) {
    const config::MachineConfig& cfg = job.delta ? *delta_cfg : cart;
    std::vector<double> wall, cpu, rss;
    Run r;
    for (int i = 0; i < reps; ++i) {
      r = run_child(job.path, cfg, 2);
      if (!r.ok) break;
      wall.push_back(r.wall_s);
      cpu.push_back(r.cpu_s);
      rss.push_back(r.max_rss_mb);
    }
    if (!r.ok) {
      std::printf("%-36s failed\n", job.name.c_str());
      continue;
    }
    config::MachineConfig cfg25 = cfg;
    cfg25.stepgen.max_step_error_us = 25.0;
    const Run r25 = run_child(job.path, cfg25, 2);
    const double w = median(wall), c = median(cpu), m = median(rss);
    std::printf("%-36s %8lld %8.0f %9.0f %10.1f %9.2fM %8.3f %8.3f %8.1f %7.3f %7.3f %6llu\n", job.name.c_str(),
                static_cast<long long>(r.lines), r.lines / w / 1e3, r.moves / w / 1e3, r.steps / w / 1e6,
                r.steps / 1e6, r.bytes_per_step, r25.bytes_per_step, m, c, w,
                static_cast<unsigned long long>(r.check_failures));
    if (job.name == "benchy_cartesian") benchy_wall = w, benchy_cpu = c;
    if (job.name == "cube20_cartesian") cube_mb = m;
    if (job.name == "benchy_x12_cartesian_LARGE") large_mb = m;
    out["files"].push_back({{"file", job.name}, {"lines", r.lines}, {"moves", r.moves}, {"steps", r.steps},
                            {"lines_per_s", r.lines / w}, {"moves_per_s", r.moves / w},
                            {"steps_per_s", r.steps / w}, {"wire_bytes_per_step_5us", r.bytes_per_step},
                            {"wire_bytes_per_step_25us", r25.bytes_per_step}, {"peak_rss_mb", m},
                            {"cpu_s", c}, {"wall_s", w}, {"check_failures", r.check_failures}});
  }
  if (!tmp_dir.empty()) fs::remove_all(tmp_dir);

  // One thread vs two on the same file, interleaved so that machine load hits both alike.
  const fs::path benchy = fs::path(dir) / "benchy_cartesian.gcode";
  if (fs::exists(benchy)) {
    std::vector<double> w1, c1, w2, c2;
    for (int i = 0; i < reps; ++i) {
      const Run a = run_child(benchy.string(), cart, 1);
      const Run b = run_child(benchy.string(), cart, 2);
      w1.push_back(a.wall_s), c1.push_back(a.cpu_s), w2.push_back(b.wall_s), c2.push_back(b.cpu_s);
    }
    std::printf("\nbenchy_cartesian, 1 vs 2 threads (interleaved, median of %d): wall %.3f -> %.3f s (x%.2f), "
                "CPU %.3f -> %.3f s\n", reps, median(w1), median(w2), median(w1) / median(w2), median(c1),
                median(c2));
    out["threads"] = {{"wall_1_s", median(w1)}, {"wall_2_s", median(w2)}, {"cpu_1_s", median(c1)},
                      {"cpu_2_s", median(c2)}};
  }
  // Klipper's batch mode (ANCHORS.md, same machine kind): benchy_cartesian 4.44 s median wall,
  // 3.09 s pinned to one core, 0.58 B/step at its 25 us bound, 53 MB -> 258 MB for 12 benchies.
  std::printf("\nKlipper batch mode (ANCHORS.md): benchy 4.44 s wall, 3.09 s one core, 0.58 B/step @25us, "
              "peak 53 MB (1 benchy) -> 258 MB (12)\n");
  if (benchy_wall > 0)
    std::printf("feedloop: benchy %.3f s wall (%.1fx faster), %.3f s CPU (%.1fx less than Klipper's one core)\n",
                benchy_wall, 4.44 / benchy_wall, benchy_cpu, 3.09 / benchy_cpu);
  if (cube_mb > 0 && large_mb > 0)
    std::printf("feedloop: peak memory cube20 %.1f MB -> 12 benchies %.1f MB (%+.1f %%)\n", cube_mb, large_mb,
                100.0 * (large_mb / cube_mb - 1.0));
  out["klipper"] = {{"benchy_wall_s", 4.44}, {"benchy_one_core_s", 3.09}, {"bytes_per_step_25us", 0.58},
                    {"peak_mb_one_benchy", 53}, {"peak_mb_12_benchies", 258}};
  out["memory"] = {{"cube20_mb", cube_mb}, {"large_mb", large_mb}};
  if (!json_path.empty()) {
    std::ofstream f(json_path);
    f << out.dump(2) << "\n";
  }
  return 0;
}
