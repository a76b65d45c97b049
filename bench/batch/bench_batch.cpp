// Batch mode over the G-code corpus: wall time, steps/s, bytes on the wire per step, peak memory,
// CPU time; for the benchy and the 12-benchy plate also the time per stage and one thread
// against two, alone and with `stress-ng --cpu 1` beside it. Every figure printed is measured
// by this program in this run.
// Usage: bench_batch [--json FILE] [--gcode-dir DIR] [--reps N] [--no-stress] [--only SUBSTRING]
//
// Every measurement runs in its own child process (fork), so the peak RSS of one file
// (getrusage(RUSAGE_SELF).ru_maxrss in the child) does not include another's. The 45 MB
// 12-benchy file is decompressed (xz -dc) into a temporary directory and removed afterwards.
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench/bench_json.hpp"
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
  int threads = 0;  // threads that stepped the joints (what auto chose)
};

// Runs batch mode on one file in a child process and reads its figures back through a pipe.
Run run_child(const std::string& file, const config::MachineConfig& cfg, int threads,
              engine::BatchStage stage = engine::BatchStage::output) {
  int fds[2];
  if (pipe(fds) != 0) return {};
  const pid_t pid = fork();
  if (pid < 0) return {};
  if (pid == 0) {
    close(fds[0]);
    Run r;
    engine::BatchOptions opt;
    opt.threads = threads;
    opt.last_stage = stage;
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
      r.threads = sum->threads;
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

// `stress-ng --cpu 1` beside the measurements while it lives; nothing when stress-ng is absent.
class CpuHog {
 public:
  bool start() {
    pid_ = fork();
    if (pid_ < 0) return false;
    if (pid_ == 0) {
      execlp("stress-ng", "stress-ng", "--cpu", "1", "--timeout", "3600s", "--quiet", nullptr);
      _exit(127);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {  // exited at once: not installed
      pid_ = -1;
      return false;
    }
    return true;
  }
  ~CpuHog() {
    if (pid_ <= 0) return;
    kill(pid_, SIGTERM);
    waitpid(pid_, nullptr, 0);
  }

 private:
  pid_t pid_ = -1;
};

const char* kStageNames[] = {"parse", "plan", "step times", "compression", "output"};
constexpr int kStages = 5;

// Time per stage, one thread: each stage run also does the stages before it, so a stage's time is
// the difference of two stages' runs (interleaved, so that load on the machine hits all alike).
// The least CPU time of each stage's runs is taken, not the median: on the shared machine a whole
// child now and then runs ~25 % slower (0.55 against 0.43 s on the benchy, in bursts that caught
// two of three runs of one stage), and the median of three then made the compression stage cost
// more than the whole pipeline (output -0.10 to -0.14 s in three runs of one afternoon). The
// spread (largest over least) is printed beside it, so a disturbed measurement shows.
nlohmann::json stage_times(const Job& job, const config::MachineConfig& cfg, int reps) {
  std::vector<double> wall[kStages], cpu[kStages];
  for (int i = 0; i < reps; ++i)
    for (int st = 0; st < kStages; ++st) {
      const Run r = run_child(job.path, cfg, 1, static_cast<engine::BatchStage>(st));
      if (!r.ok) return {};
      wall[st].push_back(r.wall_s);
      cpu[st].push_back(r.cpu_s);
    }
  std::printf(
      "\n%s, time per stage (one thread, CPU s; the least of %d runs, each stage's run minus the "
      "one before):\n",
      job.name.c_str(), reps);
  nlohmann::json out = nlohmann::json::array();
  double prev = 0.0;
  for (int st = 0; st < kStages; ++st) {
    const double c = *std::min_element(cpu[st].begin(), cpu[st].end());
    const double spread = c > 0.0 ? *std::max_element(cpu[st].begin(), cpu[st].end()) / c : 1.0;
    const double w = *std::min_element(wall[st].begin(), wall[st].end());
    std::printf("  %-12s %7.3f s  (cumulative %.3f s CPU, %.3f s wall; runs spread x%.2f)\n",
                kStageNames[st], c - prev, c, w, spread);
    out.push_back({{"stage", kStageNames[st]},
                   {"cpu_s", c - prev},
                   {"cumulative_cpu_s", c},
                   {"cumulative_wall_s", w},
                   {"cumulative_cpu_spread", spread}});
    prev = c;
  }
  return out;
}

// One thread, two, and the default (auto: two when the process may run on two cores),
// interleaved; alone, then with stress-ng --cpu 1 beside it.
nlohmann::json threads_and_load(const Job& job, const config::MachineConfig& cfg, int reps,
                                bool stress) {
  nlohmann::json out = nlohmann::json::array();
  constexpr int kSettings[] = {1, 2, 0};
  std::printf("\n%s, one thread vs two vs auto (median of %d, interleaved):\n", job.name.c_str(),
              reps);
  std::printf("  %-22s %8s %8s %8s %8s %10s %8s\n", "condition", "threads", "used", "wall_s",
              "cpu_s", "Msteps/s", "peakMB");
  for (int loaded = 0; loaded <= (stress ? 1 : 0); ++loaded) {
    CpuHog hog;
    if (loaded && !hog.start()) {
      std::printf("  with stress-ng --cpu 1: not measured (stress-ng did not start)\n");
      break;
    }
    std::vector<double> w[3], c[3], m[3], used[3];
    uint64_t steps = 0;
    for (int i = 0; i < reps; ++i)
      for (int t = 0; t < 3; ++t) {
        const Run r = run_child(job.path, cfg, kSettings[t]);
        if (!r.ok) return out;
        w[t].push_back(r.wall_s), c[t].push_back(r.cpu_s), m[t].push_back(r.max_rss_mb);
        used[t].push_back(r.threads);
        steps = r.steps;
      }
    const char* cond = loaded ? "stress-ng --cpu 1" : "alone";
    for (int t = 0; t < 3; ++t) {
      const double wall = median(w[t]);
      const std::string setting = kSettings[t] == 0 ? "auto" : std::to_string(kSettings[t]);
      std::string chosen;  // the threads each rep used, e.g. "1,2,2" for auto
      for (double u : used[t]) chosen += (chosen.empty() ? "" : ",") + std::to_string(int(u));
      std::printf("  %-22s %8s %8s %8.3f %8.3f %10.1f %8.1f\n", cond, setting.c_str(),
                  chosen.c_str(), wall, median(c[t]), static_cast<double>(steps) / wall / 1e6,
                  median(m[t]));
      out.push_back({{"condition", cond},
                     {"threads", setting},
                     {"threads_used", used[t]},
                     {"wall_s", wall},
                     {"cpu_s", median(c[t])},
                     {"steps_per_s", static_cast<double>(steps) / wall},
                     {"peak_rss_mb", median(m[t])}});
    }
  }
  return out;
}

double load_average_1min() {
  double l = -1.0;
  if (FILE* f = std::fopen("/proc/loadavg", "r")) {
    if (std::fscanf(f, "%lf", &l) != 1) l = -1.0;
    std::fclose(f);
  }
  return l;
}

}  // namespace

int main(int argc, char** argv) {
  std::string json_path, only, dir = std::string(FEEDLOOP_SHARED_DIR) + "/gcode";
  int reps = 3;
  bool stress = true;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--json") && i + 1 < argc) json_path = argv[++i];
    else if (!std::strcmp(argv[i], "--gcode-dir") && i + 1 < argc) dir = argv[++i];
    else if (!std::strcmp(argv[i], "--reps") && i + 1 < argc) reps = std::max(1, std::atoi(argv[++i]));
    else if (!std::strcmp(argv[i], "--no-stress"))
      stress = false;
    else if (!std::strcmp(argv[i], "--only") && i + 1 < argc)
      only = argv[++i];
    else {
      std::fprintf(
          stderr,
          "usage: %s [--json FILE] [--gcode-dir DIR] [--reps N] [--no-stress] [--only SUBSTRING]\n",
          argv[0]);
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
  if (fs::exists(xz) &&
      (only.empty() || std::string("benchy_x12_cartesian_LARGE").find(only) != std::string::npos)) {
    char tmpl[] = "/tmp/bench_batch_XXXXXX";
    if (mkdtemp(tmpl) != nullptr) {
      tmp_dir = tmpl;
      const std::string out = tmp_dir + "/benchy_x12_cartesian_LARGE.gcode";
      const std::string cmd = "xz -dc '" + xz.string() + "' > '" + out + "'";
      if (std::system(cmd.c_str()) == 0) jobs.push_back({"benchy_x12_cartesian_LARGE", out, false});
      else std::fprintf(stderr, "bench_batch: xz failed; skipping the 12-benchy file\n");
    }
  }
  if (!only.empty())
    std::erase_if(jobs, [&](const Job& j) { return j.name.find(only) == std::string::npos; });

  nlohmann::json out;
  out["load_average_1min_at_start"] = load_average_1min();
  out["files"] = nlohmann::json::array();
  std::printf(
      "batch mode, %d rep(s) per file (median; default threads: two when two cores are allowed; "
      "CPU = all threads of the process)\n",
      reps);
  std::printf("load average (1 min) at start: %.2f\n", load_average_1min());
  std::printf("%-36s %8s %10s %9s %8s %8s %8s %7s %7s %6s\n", "file", "lines", "Msteps/s", "steps",
              "B/st@5", "B/st@25", "peakMB", "cpu_s", "wall_s", "fails");
  for (const Job& job : jobs) {
    const config::MachineConfig& cfg = job.delta ? *delta_cfg : cart;
    std::vector<double> wall, cpu, rss;
    Run r;
    for (int i = 0; i < reps; ++i) {
      r = run_child(job.path, cfg, 0);
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
    const Run r25 = run_child(job.path, cfg25, 0);
    const double w = median(wall), c = median(cpu), m = median(rss);
    std::printf("%-36s %8lld %10.1f %8.2fM %8.3f %8.3f %8.1f %7.3f %7.3f %6llu\n", job.name.c_str(),
                static_cast<long long>(r.lines), static_cast<double>(r.steps) / w / 1e6,
                static_cast<double>(r.steps) / 1e6, r.bytes_per_step, r25.bytes_per_step, m, c, w,
                static_cast<unsigned long long>(r.check_failures));
    out["files"].push_back({{"file", job.name},
                            {"lines", r.lines},
                            {"moves", r.moves},
                            {"steps", r.steps},
                            {"steps_per_s", static_cast<double>(r.steps) / w},
                            {"wire_bytes_per_step_5us", r.bytes_per_step},
                            {"wire_bytes_per_step_25us", r25.bytes_per_step},
                            {"peak_rss_mb", m},
                            {"cpu_s", c},
                            {"wall_s", w},
                            {"check_failures", r.check_failures}});
  }

  // The benchy and the 12-benchy plate in detail.
  for (const Job& job : jobs) {
    if (job.name != "benchy_cartesian" && job.name != "benchy_x12_cartesian_LARGE") continue;
    out["detail"][job.name]["stages"] = stage_times(job, cart, reps);
    out["detail"][job.name]["threads"] = threads_and_load(job, cart, reps, stress);
  }
  if (!tmp_dir.empty()) fs::remove_all(tmp_dir);
  out["load_average_1min_at_end"] = load_average_1min();
  std::printf("\nload average (1 min) at the end: %.2f\n", load_average_1min());
  if (!json_path.empty()) {
    if (!feedloop::bench::write_json(json_path, out)) return 1;
  }
  return 0;
}
