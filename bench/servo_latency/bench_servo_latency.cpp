// Servo-loop wake-up latency: the daemon's own servo thread (engine::Machine on a MonotonicClock
// with the trivial PositionExecutor, SCHED_FIFO + mlockall as the daemon requests them) beside
// cyclictest (rt-tests) at the same period and priority, idle and under stress-ng load.
//
// Latency = wake time - absolute deadline of clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME),
// the quantity both programs measure. feedloop keeps it in engine/latency_histogram.hpp
// (log bins, x1.25 per bin; percentiles are the upper edge of the bin: conservative);
// cyclictest's histogram has 1 us bins. The cyclictest figures are also shown re-binned into
// feedloop's histogram so the two columns compare like with like.
//
// Usage: bench_servo_latency [--seconds N] [--period-us P] [--priority PRIO] [--no-stress]
//                            [--concurrent] [--stress-args "ARGS"] [--json FILE]
#include <fcntl.h>      // open
#include <signal.h>     // kill
#include <spawn.h>      // posix_spawnp
#include <sys/mman.h>   // munlockall
#include <sys/utsname.h>  // uname
#include <sys/wait.h>   // waitpid
#include <unistd.h>     // sleep

#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <system_error>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench/bench_json.hpp"
#include "core/clock.hpp"
#include "engine/latency_histogram.hpp"
#include "engine/machine.hpp"
#include "engine/position_executor.hpp"

extern char** environ;

namespace {

using feedloop::LatencyHistogram;

struct Figures {
  bool ok = false;
  std::string error;
  double p50_us = 0, p99_us = 0, max_us = 0, mean_us = 0;
  uint64_t samples = 0;
  uint64_t misses = 0;  // wake-ups later than one period
  // cyclictest only: its percentiles re-binned as feedloop's histogram
  double binned_p50_us = 0, binned_p99_us = 0;
};

struct Condition {
  std::string name;
  std::string load;  // command line of the load, empty when idle
  Figures feedloop, cyclictest;
  bool sched_fifo = false, mlocked = false;
  std::string warnings;
};

double us(int64_t ns) { return static_cast<double>(ns) / 1000.0; }

// The real servo loop: Machine + MonotonicClock + PositionExecutor, nothing submitted, so every
// cycle is a wake-up, a (trivial) servo_cycle and a status publish.
Figures run_feedloop(double seconds, double period_us, int priority, Condition& c) {
  Figures f;
  feedloop::MonotonicClock clock;
  feedloop::engine::MachineOptions opt;
  opt.servo_rate_hz = 1e6 / period_us;
  opt.realtime_priority = priority;
  opt.lock_memory = true;
  auto machine = std::make_unique<feedloop::engine::Machine>(opt, clock,
                                                              std::make_unique<feedloop::engine::PositionExecutor>());
  std::string warnings;
  try {
    if (auto s = machine->start(&warnings); !s) {
      f.error = s.error().message;
      return f;
    }
  } catch (const std::system_error& e) {
    // Seen as an unprivileged user: mlockall(MCL_FUTURE) succeeds within RLIMIT_MEMLOCK (8 MB)
    // and the next thread's stack can then not be mapped. Report it and measure without locking.
    c.warnings += std::string("Machine::start threw (") + e.what() +
                  ") after mlockall: thread stacks exceed RLIMIT_MEMLOCK; measured without memory locking\n";
    machine.reset();
    munlockall();
    opt.lock_memory = false;
    machine = std::make_unique<feedloop::engine::Machine>(opt, clock,
                                                         std::make_unique<feedloop::engine::PositionExecutor>());
    if (auto s = machine->start(&warnings); !s) {
      f.error = s.error().message;
      return f;
    }
  }
  c.warnings += warnings;
  c.sched_fifo = warnings.find("SCHED_FIFO") == std::string::npos;
  c.mlocked = opt.lock_memory && warnings.find("lock memory") == std::string::npos;
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  const feedloop::engine::ServoStatus st = machine->servo_status();
  machine->stop();
  const LatencyHistogram& h = st.latency;
  f.ok = h.samples > 0;
  if (!f.ok) f.error = "no servo cycles";
  f.samples = h.samples;
  f.p50_us = us(h.percentile_ns(0.50));
  f.p99_us = us(h.percentile_ns(0.99));
  f.max_us = us(h.max_ns);
  f.misses = st.deadline_misses;
  // Mean from the bin centres (the histogram keeps no sum): an estimate, used for nothing else.
  double acc = 0;
  for (int i = 0; i < LatencyHistogram::kBins; ++i) {
    const double lo = static_cast<double>(LatencyHistogram::edge_ns(i));
    const double hi = i + 1 < LatencyHistogram::kBins ? static_cast<double>(LatencyHistogram::edge_ns(i + 1))
                                                      : static_cast<double>(h.max_ns);
    acc += 0.5 * (lo + hi) * static_cast<double>(h.counts[static_cast<size_t>(i)]);
  }
  f.mean_us = h.samples ? acc / static_cast<double>(h.samples) / 1000.0 : 0.0;
  return f;
}

// cyclictest -m -p PRIO -i PERIOD -l LOOPS -q -h MAX: parse "# Histogram" lines "USEC COUNT",
// "# Max Latencies", "# Histogram Overflows".
Figures run_cyclictest(double seconds, double period_us, int priority) {
  Figures f;
  const long loops = static_cast<long>(seconds * 1e6 / period_us);
  const int hist_max_us = static_cast<int>(4 * period_us);
  std::ostringstream cmd;
  cmd << "cyclictest -m -p " << priority << " -i " << static_cast<long>(period_us) << " -l " << loops
      << " -q -h " << hist_max_us << " 2>&1";
  FILE* p = popen(cmd.str().c_str(), "r");
  if (!p) {
    f.error = "cannot run cyclictest";
    return f;
  }
  std::vector<uint64_t> hist(static_cast<size_t>(hist_max_us), 0);
  uint64_t overflows = 0;
  long max_us = -1;
  char line[512];
  std::string tail;
  while (std::fgets(line, sizeof line, p)) {
    long a = 0, b = 0;
    if (line[0] != '#' && std::sscanf(line, "%ld %ld", &a, &b) == 2) {
      if (a >= 0 && a < hist_max_us) hist[static_cast<size_t>(a)] += static_cast<uint64_t>(b);
    } else if (std::sscanf(line, "# Max Latencies: %ld", &a) == 1) {
      max_us = a;
    } else if (std::sscanf(line, "# Histogram Overflows: %ld", &a) == 1) {
      overflows = static_cast<uint64_t>(a);
    } else {
      tail = line;
    }
  }
  const int rc = pclose(p);
  if (rc != 0 || max_us < 0) {
    f.error = "cyclictest failed (exit " + std::to_string(WEXITSTATUS(rc)) + "): " + tail +
              " (install: apt-get install rt-tests)";
    return f;
  }
  uint64_t n = overflows;
  double sum = 0;
  LatencyHistogram binned;
  for (size_t i = 0; i < hist.size(); ++i) {
    n += hist[i];
    sum += static_cast<double>(i) * static_cast<double>(hist[i]);
    // each count at the bin's centre (cyclictest truncates to whole us)
    for (uint64_t k = 0; k < hist[i]; ++k) binned.add(static_cast<int64_t>(i) * 1000 + 500);
  }
  for (uint64_t k = 0; k < overflows; ++k) binned.add(static_cast<int64_t>(max_us) * 1000);
  auto quantile = [&](double q) {
    const auto target = static_cast<uint64_t>(q * static_cast<double>(n));
    uint64_t acc = 0;
    for (size_t i = 0; i < hist.size(); ++i) {
      acc += hist[i];
      if (acc > target) return static_cast<double>(i) + 1.0;  // upper edge of the 1 us bin
    }
    return static_cast<double>(max_us);
  };
  f.ok = n > 0;
  f.samples = n;
  f.p50_us = quantile(0.50);
  f.p99_us = quantile(0.99);
  f.max_us = static_cast<double>(max_us);
  f.mean_us = n > overflows ? sum / static_cast<double>(n - overflows) : 0.0;
  uint64_t late = overflows;
  for (size_t i = static_cast<size_t>(period_us) + 1; i < hist.size(); ++i) late += hist[i];
  f.misses = late;
  f.binned_p50_us = us(binned.percentile_ns(0.50));
  f.binned_p99_us = us(binned.percentile_ns(0.99));
  return f;
}

// A load generator in its own process group so that all its workers stop together.
struct Load {
  pid_t pid = -1;
  bool start(const std::string& args, double seconds, std::string& err) {
    std::vector<std::string> words{"stress-ng"};
    std::istringstream is(args);
    for (std::string w; is >> w;) words.push_back(w);
    words.push_back("--timeout");
    words.push_back(std::to_string(static_cast<long>(seconds) + 1) + "s");
    words.push_back("--quiet");
    std::vector<char*> argv;
    for (auto& w : words) argv.push_back(w.data());
    argv.push_back(nullptr);
    posix_spawnattr_t attr;
    posix_spawnattr_init(&attr);
    posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP);
    posix_spawnattr_setpgroup(&attr, 0);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
    const int rc = posix_spawnp(&pid, "stress-ng", &fa, &attr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    posix_spawnattr_destroy(&attr);
    if (rc != 0) {
      err = std::string("cannot start stress-ng: ") + std::strerror(rc) + " (install: apt-get install stress-ng)";
      pid = -1;
      return false;
    }
    std::this_thread::sleep_for(std::chrono::seconds(1));  // let the workers spin up
    int status = 0;
    if (waitpid(pid, &status, WNOHANG) == pid) {
      err = "stress-ng exited at once (exit " + std::to_string(WEXITSTATUS(status)) + ")";
      pid = -1;
      return false;
    }
    return true;
  }
  void stop() {
    if (pid <= 0) return;
    kill(-pid, SIGTERM);  // our own child's process group
    int status = 0;
    waitpid(pid, &status, 0);
    pid = -1;
  }
  ~Load() { stop(); }
};

void print_fig(const Figures& f) {
  if (!f.ok) {
    std::printf(" %-36s", ("(" + f.error.substr(0, 34) + ")").c_str());
    return;
  }
  std::printf(" %8.1f %8.1f %9.1f %6llu", f.p50_us, f.p99_us, f.max_us,
              static_cast<unsigned long long>(f.misses));
}

nlohmann::json json_fig(const Figures& f, bool binned) {
  nlohmann::json j = {{"ok", f.ok},
                      {"samples", f.samples},
                      {"p50_us", f.p50_us},
                      {"p99_us", f.p99_us},
                      {"max_us", f.max_us},
                      {"mean_us", f.mean_us},
                      {"deadline_misses", f.misses}};
  if (binned) {
    j["binned_p50_us"] = f.binned_p50_us;
    j["binned_p99_us"] = f.binned_p99_us;
  }
  if (!f.ok) j["error"] = f.error;
  return j;
}

}  // namespace

int main(int argc, char** argv) {
  double seconds = 10.0, period_us = 1000.0;
  int priority = 80;
  bool stress = true, concurrent = false;
  std::string stress_args = "--cpu 2 --io 1 --vm 1 --vm-bytes 128M";
  const char* json_path = nullptr;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--seconds" && i + 1 < argc) seconds = std::atof(argv[++i]);
    else if (a == "--period-us" && i + 1 < argc) period_us = std::atof(argv[++i]);
    else if (a == "--priority" && i + 1 < argc) priority = std::atoi(argv[++i]);
    else if (a == "--stress-args" && i + 1 < argc) stress_args = argv[++i];
    else if (a == "--no-stress") stress = false;
    else if (a == "--concurrent") concurrent = true;
    else if (a == "--json" && i + 1 < argc) json_path = argv[++i];
    else {
      std::fprintf(stderr,
                   "usage: %s [--seconds N] [--period-us P] [--priority PRIO] [--no-stress] "
                   "[--concurrent] [--stress-args \"ARGS\"] [--json FILE]\n",
                   argv[0]);
      return 2;
    }
  }
  if (!(seconds > 0) || !(period_us >= 50 && period_us <= 10000) || priority < 0 || priority > 99) {
    std::fprintf(stderr, "bad --seconds/--period-us/--priority\n");
    return 2;
  }
  utsname un{};
  uname(&un);
  const std::string kernel = std::string(un.release) + " " + un.version;
  const bool preempt_rt = kernel.find("PREEMPT_RT") != std::string::npos;

  std::vector<Condition> conds;
  conds.push_back({"idle", "", {}, {}, false, false, {}});
  if (stress) conds.push_back({"stress-ng", "stress-ng " + stress_args, {}, {}, false, false, {}});

  for (Condition& c : conds) {
    Load load;
    std::string err;
    const double load_s = concurrent ? seconds + 2 : 2 * seconds + 2;
    if (!c.load.empty() && !load.start(stress_args, load_s, err)) {
      c.feedloop.error = c.cyclictest.error = err;
      continue;
    }
    std::fprintf(stderr, "%s: %s %.0f s...\n", c.name.c_str(), concurrent ? "both" : "feedloop then cyclictest",
                 seconds);
    if (concurrent) {
      std::thread ct([&] { c.cyclictest = run_cyclictest(seconds, period_us, priority); });
      c.feedloop = run_feedloop(seconds, period_us, priority, c);
      ct.join();
    } else {
      c.feedloop = run_feedloop(seconds, period_us, priority, c);
      c.cyclictest = run_cyclictest(seconds, period_us, priority);
    }
    load.stop();
  }

  std::printf("servo wake-up latency, period %.0f us, SCHED_FIFO priority %d, %.0f s per condition (%s)\n",
              period_us, priority, seconds, concurrent ? "feedloop and cyclictest at the same time"
                                                       : "feedloop, then cyclictest");
  std::printf("kernel %s%s\n", un.release, preempt_rt ? " (PREEMPT_RT)" : " (not PREEMPT_RT)");
  std::printf("%-10s | %-8s %8s %9s %6s | %-8s %8s %9s %6s | %-15s\n", "", "feedloop", "", "", "",
              "cyclict.", "", "", "", "cyclictest in");
  std::printf("%-10s | %8s %8s %9s %6s | %8s %8s %9s %6s | %-15s\n", "condition", "p50 us", "p99 us",
              "max us", "misses", "p50 us", "p99 us", "max us", "misses", "feedloop bins");
  for (const Condition& c : conds) {
    std::printf("%-10s |", c.name.c_str());
    print_fig(c.feedloop);
    std::printf(" |");
    print_fig(c.cyclictest);
    if (c.cyclictest.ok)
      std::printf(" | p50 %.1f p99 %.1f", c.cyclictest.binned_p50_us, c.cyclictest.binned_p99_us);
    std::printf("\n");
  }
  for (const Condition& c : conds) {
    if (!c.warnings.empty())
      std::printf("warning (%s): %s", c.name.c_str(), c.warnings.c_str());
    std::printf("%s: feedloop servo thread SCHED_FIFO %s, mlockall %s, %llu cycles\n", c.name.c_str(),
                c.sched_fifo ? "yes" : "NOT permitted", c.mlocked ? "yes" : "NOT permitted",
                static_cast<unsigned long long>(c.feedloop.samples));
  }
  std::printf("feedloop percentiles: upper edge of a x1.25 log bin; cyclictest: 1 us bins. "
              "misses: wake-ups later than one period.\n");

  if (json_path) {
    nlohmann::json out = {{"bench", "servo_latency"}, {"period_us", period_us},
                          {"priority", priority},     {"seconds_per_condition", seconds},
                          {"concurrent", concurrent}, {"kernel", kernel},
                          {"preempt_rt", preempt_rt}, {"conditions", nlohmann::json::array()}};
    for (const Condition& c : conds)
      out["conditions"].push_back({{"name", c.name},
                                   {"load", c.load},
                                   {"sched_fifo", c.sched_fifo},
                                   {"mlockall", c.mlocked},
                                   {"feedloop", json_fig(c.feedloop, false)},
                                   {"cyclictest", json_fig(c.cyclictest, true)},
                                   {"warnings", c.warnings}});
    if (!feedloop::bench::write_json(json_path, out)) return 1;
  }
  bool ok = true;
  for (const Condition& c : conds) ok = ok && c.feedloop.ok;
  return ok ? 0 : 1;
}
