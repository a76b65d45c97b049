// bench_ident: speed and outcome of `ident fit` on simulated traces (random small moves, thesis
// Appendix D.3) of a given length, one row per case: the effects hidden in the plant, what was
// found, residual RMS before/after, wall time of the recording and of the fit.
//   bench_ident [--duration S] [--json FILE]
#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench/bench_json.hpp"
#include "ident/excitation.hpp"
#include "ident/fit.hpp"
#include "sim/experiments/gantry_recording.hpp"

namespace {

struct Row {
  std::string name, hidden, found;
  double baseline_um, augmented_um, record_s, fit_s, fit_cpu_s;
};

// CPU time of the whole process (all threads), s.
double cpu_s() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

}  // namespace

int main(int argc, char** argv) {
  using namespace feedloop;
  double duration_s = 100.0;
  std::string json_path;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--duration" && i + 1 < argc) {
      duration_s = std::atof(argv[++i]);
    } else if (a == "--json" && i + 1 < argc) {
      json_path = argv[++i];
    } else {
      std::fprintf(stderr, "usage: bench_ident [--duration S] [--json FILE]\n");
      return 2;
    }
  }
  struct Case {
    std::string name, hidden;
    char axis;
    sim::GantryEffects fx;
  };
  std::vector<Case> cases;
  cases.push_back({"x_clean", "none", 'x', {}});
  Case a{"x_periodic_backlash", "periodic_position backlash", 'x', {}};
  a.fx.periodic_position = {true, 33.93, 15.0};
  a.fx.backlash = {true, 30.0};
  cases.push_back(a);
  Case b{"y_delay_scale", "time_delay scale_error", 'y', {}};
  b.fx.time_delay = {true, 5.0};
  b.fx.scale_error = {true, 1.003};
  cases.push_back(b);

  std::vector<Row> rows;
  std::printf("%-22s %-28s %-36s %12s %12s %9s %7s %9s\n", "case", "hidden effects", "found", "before_um", "after_um",
              "record_s", "fit_s", "fit_cpu_s");
  for (const auto& c : cases) {
    sim::GantryAxisParams p = c.axis == 'x' ? sim::thesis_x_axis() : sim::thesis_y_axis();
    p.belt_span_mm = 1e6;
    p.effects = c.fx;
    ident::RandomMovesOptions ro;
    ro.duration_s = duration_s;
    const auto t0 = std::chrono::steady_clock::now();
    auto tr = sim::record_gantry_trace(p, ident::random_moves(ro), 1000.0, std::string(1, c.axis));
    if (!tr) {
      std::fprintf(stderr, "%s\n", tr.error().to_string().c_str());
      return 1;
    }
    const auto t1 = std::chrono::steady_clock::now();
    const double c1 = cpu_s();
    const auto& ax = tr.value().axes[0];
    auto r = ident::identify_axis(ax.name, ax.cmd_mm, ax.meas_mm, tr.value().period_s(), ident::FitOptions{});
    const auto t2 = std::chrono::steady_clock::now();
    const double c2 = cpu_s();
    if (!r) {
      std::fprintf(stderr, "%s\n", r.error().to_string().c_str());
      return 1;
    }
    std::string found;
    for (auto e : r.value().effects) found += std::string(found.empty() ? "" : " ") + ident::effect_name(e);
    if (found.empty()) found = "none";
    Row row{c.name, c.hidden, found, r.value().baseline_rms_um, r.value().augmented_rms_um,
            std::chrono::duration<double>(t1 - t0).count(), std::chrono::duration<double>(t2 - t1).count(), c2 - c1};
    std::printf("%-22s %-28s %-36s %12.3f %12.3f %9.2f %7.2f %9.2f\n", row.name.c_str(), row.hidden.c_str(),
                row.found.c_str(), row.baseline_um, row.augmented_um, row.record_s, row.fit_s, row.fit_cpu_s);
    rows.push_back(row);
  }
  if (!json_path.empty()) {
    nlohmann::json out = {{"duration_s", duration_s}, {"rows", nlohmann::json::array()}};
    for (const Row& r : rows)
      out["rows"].push_back({{"case", r.name},
                             {"hidden", r.hidden},
                             {"found", r.found},
                             {"before_um", r.baseline_um},
                             {"after_um", r.augmented_um},
                             {"record_s", r.record_s},
                             {"fit_s", r.fit_s},
                             {"fit_cpu_s", r.fit_cpu_s}});
    if (!feedloop::bench::write_json(json_path, out)) return 1;
  }
  return 0;
}
