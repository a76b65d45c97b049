// Cost of one device-loop tick of one axis (drivers/device/axis_loop.hpp) on this machine, and
// the Cortex-M4 cycle count that implies. The loop runs as in the virtual MCU: a moving target
// streamed as r(t) knots, an encoder with noise, the motor following with the loop's own steps.
// Usage: bench_device_loop [--ticks N] [--ipc-ratio R] [--json FILE]
//
// Conversion to the MCU (an estimate, not a measurement on an M4):
//   M4 cycles = host ns x host clock (GHz, from /proc/cpuinfo) x R,
// with R the assumed ratio of this host's instructions per cycle to the M4's on this code
// (default 3: a superscalar x86 core retires ~2-4 instructions per cycle on scalar float/int code,
// the M4 ~1; the loop uses float only - the M4's FPU is single precision - and int64 adds and
// multiplies, which the M4 does in 1-3 cycles). The thesis's budget: < 0.15 ms per update at
// 1 kHz on a 72 MHz Teensy 3.1 (Sect. 4.6).
#include <time.h>  // clock_gettime

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench/bench_json.hpp"
#include "drivers/device/axis_loop.hpp"

using namespace feedloop::device;

namespace {

double now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return 1e9 * static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec);
}

double thread_cpu_ns() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return 1e9 * static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec);
}

double host_ghz() {
  std::ifstream f("/proc/cpuinfo");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("cpu MHz", 0) == 0) return std::atof(line.substr(line.find(':') + 1).c_str()) / 1000.0;
  return 0.0;
}

struct Row {
  double control_hz = 0;
  long ticks = 0;
  double mean_ns = 0, p50_ns = 0, p99_ns = 0, max_ns = 0;
};

Row run(double control_hz, long ticks) {
  const double clock_hz = 168e6;  // the M4's clock as the MCU tick rate
  const int64_t period = static_cast<int64_t>(clock_hz / control_hz);
  AxisLoop loop;
  loop.init(static_cast<float>(clock_hz));
  LoopParams p;
  p.enabled = true;
  p.period_ticks = static_cast<uint32_t>(period);
  p.nm_per_count_q16 = 490u << 16;
  p.nm_per_step_q16 = 10603u << 16;
  p.slip_cycle_nm = 678000.0f;
  p.deflection_s2 = 4.1e-6f;
  p.deflection_s = 0.007f;
  loop.stage(p, 0);
  // Target: 50 mm +- 40 mm sine at 1 Hz (peak 250 mm/s), knots every 2 ms, 100 ms ahead.
  auto r_nm = [&](int64_t c) { return 50e6 + 40e6 * std::sin(2 * M_PI * static_cast<double>(c) / clock_hz); };
  const int64_t knot_dt = static_cast<int64_t>(0.002 * clock_hz);
  int64_t next_knot = 0;
  int64_t motor_steps = static_cast<int64_t>(r_nm(0) / 10603.0), device_steps = 0;
  uint32_t rng = 12345;
  std::vector<double> samples;
  samples.reserve(static_cast<size_t>(ticks / 16 + 1));
  double total_cpu = 0;
  LoopTickIn in;
  LoopTickOut out;
  LoopEvent ev;
  const double cpu0 = thread_cpu_ns();
  for (long k = 0; k < ticks; ++k) {
    const int64_t clock = k * period;
    while (next_knot <= clock + static_cast<int64_t>(0.1 * clock_hz)) {
      loop.push_target({next_knot, static_cast<int64_t>(r_nm(next_knot))});
      next_knot += knot_dt;
    }
    // Encoder: the carriage 2 um behind r plus +-1 count of noise.
    rng = rng * 1664525u + 1013904223u;
    const double y = r_nm(clock) - 2000.0;
    in.clock = clock;
    in.encoder_counts = static_cast<int64_t>(y / 490.0) + static_cast<int64_t>(rng >> 31);
    in.motor_steps = motor_steps;
    in.device_steps = device_steps;
    if ((k & 15) == 0) {  // per-tick timing on every 16th tick (the clock read costs ~20 ns)
      const double t0 = now_ns();
      loop.tick(in, out);
      samples.push_back(now_ns() - t0);
    } else {
      loop.tick(in, out);
    }
    device_steps += out.extra_steps;
    motor_steps = static_cast<int64_t>(r_nm(clock + period) / 10603.0) + device_steps;
    while (loop.pop_event(ev)) {
    }
  }
  total_cpu = thread_cpu_ns() - cpu0;
  // The harness alone (target, encoder model, sin): subtract its cost.
  const double cpu1 = thread_cpu_ns();
  volatile double sink = 0;
  for (long k = 0; k < ticks; ++k) {
    const int64_t clock = k * period;
    rng = rng * 1664525u + 1013904223u;
    sink = sink + r_nm(clock) + r_nm(clock + period) + static_cast<double>(rng >> 31);
    if (clock % knot_dt < period) sink = sink + r_nm(clock);
  }
  const double harness = thread_cpu_ns() - cpu1;
  if (loop.state() != LoopState::kRunning) {
    std::fprintf(stderr, "loop left running state (%d) at %.0f Hz\n", static_cast<int>(loop.state()), control_hz);
    std::exit(1);
  }
  std::sort(samples.begin(), samples.end());
  Row row;
  row.control_hz = control_hz;
  row.ticks = ticks;
  row.mean_ns = (total_cpu - harness) / static_cast<double>(ticks);
  row.p50_ns = samples[samples.size() / 2];
  row.p99_ns = samples[samples.size() * 99 / 100];
  row.max_ns = samples.back();
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  long ticks = 2000000;
  double ipc_ratio = 3.0;
  std::string json;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--json") && i + 1 < argc) json = argv[++i];
    else if (!std::strcmp(argv[i], "--ticks") && i + 1 < argc) ticks = std::atol(argv[++i]);
    else if (!std::strcmp(argv[i], "--ipc-ratio") && i + 1 < argc) ipc_ratio = std::atof(argv[++i]);
    else { std::fprintf(stderr, "usage: %s [--ticks N] [--ipc-ratio R] [--json FILE]\n", argv[0]); return 2; }
  }
  const double ghz = host_ghz();
  std::vector<Row> rows = {run(1000.0, ticks), run(10000.0, ticks)};
  std::printf("device loop, one axis; host %.2f GHz; M4 cycles = mean ns x %.2f GHz x %.1f (assumed IPC ratio)\n",
              ghz, ghz, ipc_ratio);
  std::printf("%-9s %9s %8s %8s %8s %8s %10s %9s %10s\n", "rate", "ticks", "mean_ns", "p50_ns", "p99_ns", "max_ns",
              "M4_cycles", "M4_us", "M4_%period");
  for (const Row& r : rows) {
    const double cycles = r.mean_ns * ghz * ipc_ratio;
    const double us = cycles / 168.0;
    std::printf("%-9s %9ld %8.1f %8.0f %8.0f %8.0f %10.0f %9.2f %10.2f\n",
                r.control_hz >= 10000 ? "10 kHz" : "1 kHz", r.ticks, r.mean_ns, r.p50_ns, r.p99_ns, r.max_ns, cycles, us,
                100.0 * us * 1e-6 * r.control_hz);
  }
  std::printf("p50/p99/max: every 16th tick timed alone with CLOCK_MONOTONIC (includes ~20 ns of clock read).\n");
  if (!json.empty()) {
    nlohmann::json out = {
        {"host_ghz", ghz}, {"ipc_ratio", ipc_ratio}, {"rows", nlohmann::json::array()}};
    for (const Row& r : rows)
      out["rows"].push_back({{"control_hz", r.control_hz},
                             {"ticks", r.ticks},
                             {"mean_ns", r.mean_ns},
                             {"p50_ns", r.p50_ns},
                             {"p99_ns", r.p99_ns},
                             {"max_ns", r.max_ns},
                             {"m4_cycles", r.mean_ns * ghz * ipc_ratio}});
    if (!feedloop::bench::write_json(json, out)) return 1;
  }
  return 0;
}
