// bench_sim_machine: a G-code program through the motion executor, the MCU bridge, mock links,
// drifting virtual MCUs and the plant simulator, one servo cycle per millisecond of virtual time.
// Prints, per machine: simulated seconds per wall second, servo cycle cost (mean, p99, max, in
// microseconds of CPU time), steps executed; with --json FILE writes the same figures.
//
//   build/bench/sim_machine/bench_sim_machine [--json FILE]
#include <time.h>  // clock_gettime

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench/bench_json.hpp"
#include "config/config.hpp"
#include "engine/config_mapping.hpp"
#include "engine/mcu_bridge.hpp"
#include "engine/motion_executor.hpp"
#include "gcode/parser.hpp"

namespace {

using namespace feedloop;

double cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

struct Figures {
  std::string machine;
  double sim_s = 0, cpu_s = 0, ratio = 0, mean_us = 0, p99_us = 0, max_us = 0;
  unsigned long long steps = 0;
};

// A square spiral: steady printing-like motion on every motor.
std::string program(bool delta) {
  std::ostringstream g;
  g << "G90\nG28\nG1 Z5 F600\n";  // homed first (the default refuses moves before)
  for (int i = 0; i < 40; ++i) {
    const double r = 5.0 + i * 1.0;
    const double c = delta ? 0.0 : 100.0;
    g << "G1 X" << c - r << " Y" << c - r << " E" << i * 0.4 << " F6000\n";
    g << "G1 X" << c + r << " Y" << c - r << " E" << i * 0.4 + 0.1 << "\n";
    g << "G1 X" << c + r << " Y" << c + r << " E" << i * 0.4 + 0.2 << "\n";
    g << "G1 X" << c - r << " Y" << c + r << " E" << i * 0.4 + 0.3 << "\n";
  }
  return g.str();
}

Figures run(const std::string& name, const config::MachineConfig& cfg, bool delta) {
  Figures f;
  f.machine = name;
  auto b = engine::make_mcu_bridge(cfg);
  if (!b.ok()) {
    std::fprintf(stderr, "%s: %s\n", name.c_str(), b.error().message.c_str());
    return f;
  }
  std::shared_ptr<engine::McuBridge> bridge = b.value();
  engine::StepPipelineParams sp;
  sp.steps_per_mm = engine::steps_per_mm(cfg);
  sp.mcu_clock_hz = static_cast<double>(cfg.stepgen.mcu_clock_hz);
  engine::MotionOptions mo;
  mo.max_buffered_s = 1e6;
  mo.input_pause_flush_s = 0.0;
  engine::MotionExecutor ex(engine::planner_config(cfg), sp, bridge, mo);
  ex.set_backend(bridge.get());
  std::atomic<bool> cancel{false};
  int64_t now = 1'000'000'000;
  std::vector<double> cycle_us;
  cycle_us.reserve(200000);
  auto cycle = [&] {
    const double t0 = cpu_s();
    ex.servo_cycle(now += 1'000'000, false);
    cycle_us.push_back((cpu_s() - t0) * 1e6);
  };
  // G28 homes through the endstops and waits for the machine: its cycles run here (counted).
  ex.set_inline_driver(cycle);
  const double c0 = cpu_s();
  std::istringstream in(program(delta));
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    auto cmd = gcode::parse_line(line, SourceLocation{"bench", ++n, 0});
    if (cmd.ok()) (void)ex.execute(cmd.value(), cancel);
  }
  ex.idle_tick(cancel);
  for (int i = 0; i < 200000 && (i < 2000 || ex.motion_pending()); ++i) cycle();
  f.cpu_s = cpu_s() - c0;
  f.sim_s = static_cast<double>(cycle_us.size()) * 1e-3;
  f.ratio = f.sim_s / f.cpu_s;
  double sum = 0;
  for (double c : cycle_us) sum += c;
  f.mean_us = sum / static_cast<double>(cycle_us.size());
  std::sort(cycle_us.begin(), cycle_us.end());
  f.p99_us = cycle_us[cycle_us.size() * 99 / 100];
  f.max_us = cycle_us.back();
  for (int j = 0; j < engine::kJoints; ++j) f.steps += bridge->timing(j).steps_executed;
  return f;
}

}  // namespace

int main(int argc, char** argv) {
  const char* json = nullptr;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--json") == 0 && i + 1 < argc) json = argv[++i];
    else {
      std::fprintf(stderr, "usage: %s [--json FILE]\n", argv[0]);
      return 2;
    }
  }
  std::vector<Figures> out;
  out.push_back(run("cartesian", config::default_config(), false));
  auto dcfg = config::load_config_file(FEEDLOOP_SOURCE_DIR "/config/examples/delta_sim.yaml");
  if (dcfg.ok()) out.push_back(run("delta", dcfg.value(), true));
  std::printf("%-10s %10s %10s %12s %12s %12s %12s %12s\n", "machine", "sim_s", "cpu_s", "sim/cpu", "cycle_mean_us",
              "cycle_p99_us", "cycle_max_us", "steps");
  for (const Figures& f : out)
    std::printf("%-10s %10.2f %10.2f %12.2f %12.1f %12.1f %12.1f %12llu\n", f.machine.c_str(), f.sim_s, f.cpu_s,
                f.ratio, f.mean_us, f.p99_us, f.max_us, f.steps);
  if (json != nullptr) {
    nlohmann::json j = {{"benchmark", "sim_machine"}, {"results", nlohmann::json::array()}};
    for (const Figures& f : out)
      j["results"].push_back({{"machine", f.machine},
                              {"sim_s", f.sim_s},
                              {"cpu_s", f.cpu_s},
                              {"sim_per_cpu", f.ratio},
                              {"cycle_mean_us", f.mean_us},
                              {"cycle_p99_us", f.p99_us},
                              {"cycle_max_us", f.max_us},
                              {"steps", f.steps}});
    if (!feedloop::bench::write_json(json, j)) return 1;
  }
  return 0;
}
