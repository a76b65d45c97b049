// Pressure advance on the compliant extruder (docs/pressure_advance.md): a G-code file planned by
// the daemon's planner, the extruder motor driven by e(t) (advance off) or Klipper's smoothed
// e_adv(t), in whole steps, into sim/extruder_plant; the extruded-volume error
// integral |q_noz - q_cmd| dt, for a sweep of K, on two plants (Bowden, direct drive).
//   bench_extruder [--gcode FILE] [--json FILE] [--k-max S] [--k-step S]
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench/bench_json.hpp"
#include "planner/config.hpp"
#include "sim/experiments/extrusion_error.hpp"

using namespace feedloop;

namespace {

struct Row {
  std::string plant;
  double k_s, smooth_s, error_mm3, corner_mm3, ratio, max_v;
};

struct Plant {
  const char* name;
  sim::ExtruderPlantParams p;
};

// K is stepped by repeated addition (0.02 + 0.02 + ...): written to 4 decimals (0.1 ms), the K the
// sweep means, not as 0.06000000000000001.
double k_rounded(double k_s) {
  return std::round(k_s * 1e4) / 1e4;
}

}  // namespace

int main(int argc, char** argv) {
  std::string gcode = std::string(FEEDLOOP_SOURCE_DIR) + "/examples/gcode/cube20_3layers.gcode";
  std::string json_path;
  double k_max = 0.6, k_step = 0.02;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--gcode") && i + 1 < argc)
      gcode = argv[++i];
    else if (!std::strcmp(argv[i], "--json") && i + 1 < argc)
      json_path = argv[++i];
    else if (!std::strcmp(argv[i], "--k-max") && i + 1 < argc)
      k_max = std::atof(argv[++i]);
    else if (!std::strcmp(argv[i], "--k-step") && i + 1 < argc)
      k_step = std::atof(argv[++i]);
    else {
      std::fprintf(stderr,
                   "usage: bench_extruder [--gcode FILE] [--json FILE] [--k-max S] [--k-step S]\n");
      return 2;
    }
  }
  std::ifstream in(gcode);
  if (!in) {
    std::fprintf(stderr, "cannot read %s\n", gcode.c_str());
    return 1;
  }
  std::stringstream ss;
  ss << in.rdbuf();
  auto planned = sim::plan_gcode(ss.str(), gcode.substr(gcode.find_last_of('/') + 1),
                                 planner::PlannerConfig{});
  if (!planned.ok()) {
    std::fprintf(stderr, "%s\n", planned.error().to_string().c_str());
    return 1;
  }
  const sim::PlannedPrint& print = planned.value();
  std::printf("G-code: %s, %zu moves, %.0f mm of extruding path\n", gcode.c_str(),
              print.moves.size(), print.extruding_path_mm);

  std::vector<Plant> plants(2);
  plants[0].name = "bowden";
  plants[1].name = "direct";
  plants[1].p.stiffness_n_per_mm = 60.0;
  plants[1].p.play_mm = 0.02;
  std::vector<Row> rows, summary;
  for (const Plant& pl : plants) {
    sim::ExtrusionRunOptions o;
    o.plant = pl.p;
    const sim::ExtruderPlant probe(pl.p);
    std::printf(
        "\nplant %s: k_f %.0f N/mm, play %.2f mm, q = c p^%.1f (%.0f N at %.0f mm^3/s), melt lag "
        "%.0f ms; "
        "linearised tau %.0f ms at 2 mm^3/s, %.0f ms at 5, %.0f ms at 10\n",
        pl.name, pl.p.stiffness_n_per_mm, pl.p.play_mm, pl.p.flow_exponent, pl.p.force_ref_n,
        pl.p.flow_ref_mm3_s, pl.p.melt_lag_s * 1e3, probe.time_constant_s(2.0) * 1e3,
        probe.time_constant_s(5.0) * 1e3, probe.time_constant_s(10.0) * 1e3);
    std::printf("%-8s %8s %10s %12s %12s %8s %12s\n", "plant", "K_s", "smooth_s", "error_mm3",
                "corners_mm3", "ratio", "max_v_mm_s");
    o.advance_s = 0.0;
    const sim::ExtrusionResult off = sim::run_extrusion(print, o);
    Row best{
        pl.name, 0.0, 0.0, off.error_mm3, off.corner_error_mm3, 1.0, off.max_motor_velocity_mm_s};
    auto print_row = [&](const Row& r) {
      std::printf("%-8s %8.3f %10.3f %12.3f %12.3f %8.3f %12.2f\n", r.plant.c_str(), r.k_s,
                  r.smooth_s, r.error_mm3, r.corner_mm3, r.ratio, r.max_v);
    };
    print_row(best);
    rows.push_back(best);
    for (double k = k_step; k <= k_max + 1e-9; k += k_step) {
      o.advance_s = k;
      const sim::ExtrusionResult res = sim::run_extrusion(print, o);
      Row r{pl.name,
            k,
            o.smooth_time_s,
            res.error_mm3,
            res.corner_error_mm3,
            res.error_mm3 / off.error_mm3,
            res.max_motor_velocity_mm_s};
      print_row(r);
      rows.push_back(r);
      if (r.error_mm3 < best.error_mm3) best = r;
    }
    // The tuned K with other smoothing windows.
    for (double st : {0.02, 0.08, 0.16}) {
      o.advance_s = best.k_s;
      o.smooth_time_s = st;
      const sim::ExtrusionResult res = sim::run_extrusion(print, o);
      Row r{pl.name,
            best.k_s,
            st,
            res.error_mm3,
            res.corner_error_mm3,
            res.error_mm3 / off.error_mm3,
            res.max_motor_velocity_mm_s};
      print_row(r);
      rows.push_back(r);
    }
    summary.push_back(Row{pl.name, 0.0, 0.0, off.error_mm3, off.corner_error_mm3, 1.0,
                          off.max_motor_velocity_mm_s});
    summary.push_back(best);
    std::printf("commanded %.1f mm^3 over %.1f s of print\n", off.commanded_mm3, off.print_time_s);
  }
  std::printf(
      "\nsummary: extruded-volume error, pressure advance off vs the tuned K (smooth_time 0.040 "
      "s)\n");
  std::printf("%-8s %14s %10s %14s %16s %8s\n", "plant", "off_error_mm3", "tuned_K_s",
              "on_error_mm3", "corners off->on", "ratio");
  for (size_t i = 0; i + 1 < summary.size(); i += 2) {
    const Row& a = summary[i];
    const Row& b = summary[i + 1];
    std::printf("%-8s %14.3f %10.3f %14.3f %7.3f->%-7.3f %8.3f\n", a.plant.c_str(), a.error_mm3,
                b.k_s, b.error_mm3, a.corner_mm3, b.corner_mm3, b.error_mm3 / a.error_mm3);
  }
  if (!json_path.empty()) {
    nlohmann::json j = {{"gcode", gcode.substr(gcode.find_last_of('/') + 1)},
                        {"rows", nlohmann::json::array()},
                        {"summary", nlohmann::json::array()}};
    for (const Row& r : rows)
      j["rows"].push_back({{"plant", r.plant},
                           {"k_s", k_rounded(r.k_s)},
                           {"smooth_time_s", r.smooth_s},
                           {"error_mm3", r.error_mm3},
                           {"corner_error_mm3", r.corner_mm3},
                           {"ratio", r.ratio},
                           {"max_motor_velocity_mm_s", r.max_v}});
    for (size_t i = 0; i + 1 < summary.size(); i += 2)
      j["summary"].push_back({{"plant", summary[i].plant},
                              {"off_error_mm3", summary[i].error_mm3},
                              {"tuned_k_s", k_rounded(summary[i + 1].k_s)},
                              {"on_error_mm3", summary[i + 1].error_mm3},
                              {"ratio", summary[i + 1].error_mm3 / summary[i].error_mm3}});
    if (!feedloop::bench::write_json(json_path, j)) return 1;
  }
  return 0;
}
