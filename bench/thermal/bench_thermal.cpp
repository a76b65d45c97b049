// bench_thermal: 50 normal heat-ups (extruder and bed, targets and part-fan changes varied, noise
// seeds varied) on the simulated printer's thermal plants, in virtual time, with the protection of
// the default config; prints how close each rule came to tripping (the margins), then injects each
// fault and prints its detection time. Usage: bench_thermal [--runs N] [--json FILE]
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
#include "config/config.hpp"
#include "engine/simulated_printer.hpp"
#include "engine/thermal_config.hpp"
#include "sim/thermal_plant.hpp"

using namespace feedloop;

namespace {

struct Margins {
  double watch_headroom_c = 1e9, below_hyst_s = 0, verify_error = 0, stuck_s = 0,
         overshoot_c = -1e9;
  double settle_s = 0, final_err_c = 0;
  int faults = 0;
};

// The times below are counted on the 0.05 s steps of virtual time (t += 0.05): written to 0.01 s as
// the tables show them, not as 77.64999999999773.
double to_hundredths(double s) {
  return std::round(s * 100.0) / 100.0;
}

std::unique_ptr<engine::ThermalLoop> make(uint64_t seed) {
  config::MachineConfig cfg = config::default_config();
  cfg.simulator.seed = seed;
  auto loop = std::move(engine::make_thermal_loop(cfg).value());
  loop->start(0.0);
  return loop;
}

}  // namespace

int main(int argc, char** argv) {
  int runs = 50;
  const char* json_path = nullptr;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--json") == 0 && i + 1 < argc) {
      json_path = argv[++i];
    } else if (std::strcmp(argv[i], "--runs") == 0 && i + 1 < argc) {
      runs = std::atoi(argv[++i]);
    } else {
      std::fprintf(stderr, "usage: %s [--runs N] [--json FILE]\n", argv[0]);
      return 2;
    }
  }
  const config::MachineConfig& cfg = config::default_config();
  Margins m[2];
  for (int r = 0; r < runs; ++r) {
    auto loop = make(static_cast<uint64_t>(r + 1));
    // Targets across the range a print uses; the fan changes at run-dependent times.
    const double target[2] = {180.0 + (r % 9) * 10.0, 45.0 + (r % 7) * 5.0};
    for (int h = 0; h < 2; ++h) (void)loop->set_target(h, target[h]);
    double settled[2] = {-1, -1};
    const double fan_on = 150.0 + 7.0 * (r % 11), fan_mid = fan_on + 90.0,
                 fan_off = fan_mid + 120.0;
    bool faulted = false;
    for (double t = 0.05; t <= 720.0 && !faulted; t += 0.05) {
      if (std::abs(t - fan_on) < 0.025) (void)loop->set_fan(0, 1.0, t);
      if (std::abs(t - fan_mid) < 0.025) (void)loop->set_fan(0, 0.3 + 0.05 * (r % 5), t);
      if (std::abs(t - fan_off) < 0.025) (void)loop->set_fan(0, 0.0, t);
      if (auto f = loop->step_to(t)) {
        std::printf("run %d: FALSE TRIP: %s\n", r, f->c_str());
        faulted = true;
        for (auto& mm : m) ++mm.faults;
      }
      for (int h = 0; h < 2; ++h)
        if (settled[h] < 0 && loop->reached(h, false, t)) settled[h] = t;
    }
    for (int h = 0; h < 2; ++h) {
      const thermal::ProtectionMargins pm = loop->margins(h);
      m[h].watch_headroom_c = std::min(m[h].watch_headroom_c, pm.min_watch_headroom_c);
      m[h].below_hyst_s = std::max(m[h].below_hyst_s, pm.max_below_hysteresis_s);
      m[h].verify_error = std::max(m[h].verify_error, pm.max_verify_error_cs);
      m[h].stuck_s = std::max(m[h].stuck_s, pm.max_stuck_s);
      m[h].overshoot_c = std::max(m[h].overshoot_c, pm.max_temp_c - target[h]);
      m[h].settle_s = std::max(m[h].settle_s, settled[h]);
      m[h].final_err_c = std::max(m[h].final_err_c, std::abs(loop->temp_c(h) - target[h]));
    }
  }
  std::printf(
      "%d normal heat-ups (extruder 180-260 C, bed 45-75 C, part fan on/partial/off), default "
      "protection\n\n",
      runs);
  std::printf("%-9s %7s | %-26s %-26s %-26s %-22s %-20s | %9s %9s\n", "heater", "trips",
              "watch: min gain margin", "runaway: max s below hyst", "verify: max error (C*s)",
              "stuck: max s same adc", "max overshoot", "settle s", "final |e|");
  const char* names[2] = {"extruder", "bed"};
  for (int h = 0; h < 2; ++h) {
    const auto& p = cfg.heaters[static_cast<size_t>(h)].protection;
    char a[64], b[64], c[64], d[64], e[64];
    std::snprintf(a, sizeof a, "%+.2f C (needs >= 0)",
                  m[h].watch_headroom_c > 1e8 ? 0.0 : m[h].watch_headroom_c);
    std::snprintf(b, sizeof b, "%.1f s (limit %.0f s)", m[h].below_hyst_s, p.runaway_period_s);
    std::snprintf(c, sizeof c, "%.1f (limit %.0f)", m[h].verify_error, p.verify_max_error);
    std::snprintf(d, sizeof d, "%.1f s (limit %.0f s)", m[h].stuck_s, p.stuck_period_s);
    std::snprintf(e, sizeof e, "%.2f C", m[h].overshoot_c);
    std::printf("%-9s %7d | %-26s %-26s %-26s %-22s %-20s | %9.1f %9.2f\n", names[h], m[h].faults,
                a, b, c, d, e, m[h].settle_s, m[h].final_err_c);
  }

  // Each fault, injected at temperature (after settling) and during the heat-up (at 15 s).
  struct Det {
    std::string heater, phase, fault, message;
    double after_s;
  };
  std::vector<Det> dets;
  const sim::ThermalFaultKind kinds[] = {
      sim::ThermalFaultKind::kThermistorOpen, sim::ThermalFaultKind::kThermistorShort,
      sim::ThermalFaultKind::kHeaterOutOfBlock, sim::ThermalFaultKind::kHeaterStuckOn,
      sim::ThermalFaultKind::kSensorStuck};
  for (int h = 0; h < 2; ++h)
    for (int phase = 0; phase < 2; ++phase)
      for (auto k : kinds) {
        auto loop = make(7);
        (void)loop->set_target(h, h == 0 ? 210.0 : 60.0);
        double t = 0.0;
        const double t_inject = phase == 0 ? 15.0 : 0.0;
        for (; t < 900.0; t += 0.05) {
          (void)loop->step_to(t);
          if (phase == 0 && t >= t_inject) break;
          if (phase == 1 && loop->reached(h, false, t)) break;
        }
        if (phase == 1) {
          const double t_end = t + 30.0;
          for (; t < t_end; t += 0.05) (void)loop->step_to(t);
        }
        (void)loop->step_to(t);  // the device has sampled up to t: the fault acts from here on
        const double ti = t;
        engine::simulated_thermal_plant(loop->link(), h)->inject(ti, k);
        std::string msg = "NOT CAUGHT";
        double after = -1;
        for (; t < ti + 400.0; t += 0.05)
          if (auto f = loop->step_to(t)) {
            msg = *f;
            after = t - ti;
            break;
          }
        dets.push_back(
            {names[h], phase == 0 ? "heating" : "at temp", sim::to_string(k), msg, after});
      }
  std::printf(
      "\nfault detection (time from injection to the fault; the message as the user sees it)\n");
  std::printf("%-9s %-8s %-20s %9s  %s\n", "heater", "phase", "fault", "after s", "message");
  for (const Det& d : dets)
    std::printf("%-9s %-8s %-20s %9.2f  %s\n", d.heater.c_str(), d.phase.c_str(), d.fault.c_str(),
                d.after_s, d.message.c_str());

  if (json_path) {
    nlohmann::json out = {
        {"runs", runs}, {"margins", nlohmann::json::array()}, {"faults", nlohmann::json::array()}};
    for (int h = 0; h < 2; ++h)
      out["margins"].push_back({{"heater", names[h]},
                                {"false_trips", m[h].faults},
                                {"min_watch_headroom_c", m[h].watch_headroom_c},
                                {"max_below_hysteresis_s", to_hundredths(m[h].below_hyst_s)},
                                {"max_verify_error", m[h].verify_error},
                                {"max_stuck_s", to_hundredths(m[h].stuck_s)},
                                {"max_overshoot_c", m[h].overshoot_c},
                                {"max_settle_s", to_hundredths(m[h].settle_s)}});
    for (const Det& d : dets)
      out["faults"].push_back({{"heater", d.heater},
                               {"phase", d.phase},
                               {"fault", d.fault},
                               {"after_s", to_hundredths(d.after_s)}});
    if (!feedloop::bench::write_json(json_path, out)) return 1;
  }
  int false_trips = m[0].faults;
  return false_trips == 0 ? 0 : 1;
}
