// Planner benchmark: for each corpus file, G-code lines/s and moves/s of interpreter + lookahead
// (commands parsed beforehand, so only the planner is timed), and with joint-space output; then a
// comparison of junction deviation and the sharp-corner speed assignment (Eq. 63-69) on the star
// and benchy files: total print time and junction speeds at corners.
//   bench_planner [--json FILE] [--corpus DIR] [--runs N]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench/bench_json.hpp"
#include "gcode/parser.hpp"
#include "planner/interpreter.hpp"
#include "planner/joint_output.hpp"
#include "planner/junction.hpp"
#include "planner/kinematics.hpp"
#include "planner/lookahead.hpp"

using namespace feedloop;
using namespace feedloop::planner;

namespace {

PlannerConfig config_for(const std::string& name) {
  PlannerConfig c;
  if (name.find("delta") != std::string::npos) {
    c.kinematics = KinematicsKind::delta;
    c.min_position_mm = {-135.0, -135.0, 0.0, -1e12};
    c.max_position_mm = {135.0, 135.0, 300.0, 1e12};
    c.home_position_mm = {0.0, 0.0, 300.0, 0.0};
    c.max_axis_velocity_mm_s = {300.0, 300.0, 300.0, 120.0};
    c.max_axis_accel_mm_s2 = {3000.0, 3000.0, 3000.0, 5000.0};
  } else {
    c.min_position_mm = {0.0, 0.0, 0.0, -1e12};
    c.max_position_mm = {220.0, 220.0, 250.0, 1e12};
  }
  return c;
}

struct Loaded {
  std::vector<gcode::Command> cmds;
  long lines = 0;
};

Loaded load(const std::string& path) {
  Loaded l;
  std::ifstream in(path);
  std::string line;
  SourceLocation where{std::filesystem::path(path).filename().string(), 0, 0};
  gcode::Command cmd;
  while (std::getline(in, line)) {
    ++l.lines;
    ++where.line;
    if (gcode::parse_line(line, where, cmd) && !cmd.empty()) l.cmds.push_back(cmd);
  }
  return l;
}

// Counts and keeps junction statistics; optionally emits joint segments.
struct Stats : MoveSink, JointSink {
  const JointEmitter* emitter = nullptr;
  long moves = 0, segments = 0;
  bool have_prev = false;
  PlannedMove prev;
  std::vector<std::pair<double, double>> corners;  // (angle deg, junction speed) of kinematic junctions
  bool keep_corners = false;
  void on_move(const PlannedMove& m) override {
    ++moves;
    if (emitter) emitter->emit(m, *this);
    if (keep_corners) {
      if (have_prev && prev.kinematic && m.kinematic) {
        corners.emplace_back(corner_angle_deg(prev.unit.data(), m.unit.data()), m.v_entry_mm_s);
      }
      prev = m;
      have_prev = true;
    }
  }
  void on_joint_segment(int, const JointSegment&) override { ++segments; }
};

struct RunResult {
  double wall_s = 0.0, print_time_s = 0.0;
  long moves = 0, segments = 0, rejected = 0, forced = 0;
  std::vector<std::pair<double, double>> corners;
};

RunResult run(const Loaded& l, const PlannerConfig& cfg, bool joints, bool corners) {
  RunResult r;
  auto kin = make_kinematics(cfg);
  JointEmitter em(*kin, cfg.servo_period_s);
  Stats st;
  st.keep_corners = corners;
  if (joints) st.emitter = &em;
  Planner planner(cfg, st);
  Interpreter in(cfg, *kin, planner);
  const auto t0 = std::chrono::steady_clock::now();
  for (const gcode::Command& c : l.cmds) {
    if (!in.execute(c)) ++r.rejected;
  }
  planner.flush();
  r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.print_time_s = planner.print_time_s();
  r.forced = static_cast<long>(planner.forced_flushes());
  r.moves = st.moves;
  r.segments = st.segments;
  r.corners = std::move(st.corners);
  return r;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  std::string json_path, corpus = std::string(FEEDLOOP_SHARED_DIR) + "/gcode";
  int runs = 3;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--json") && i + 1 < argc) json_path = argv[++i];
    else if (!std::strcmp(argv[i], "--corpus") && i + 1 < argc) corpus = argv[++i];
    else if (!std::strcmp(argv[i], "--runs") && i + 1 < argc) runs = std::max(1, std::atoi(argv[++i]));
    else {
      std::fprintf(stderr, "usage: bench_planner [--json FILE] [--corpus DIR] [--runs N]\n");
      return 2;
    }
  }
  std::vector<std::string> files;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(corpus, ec)) {
    if (e.path().extension() == ".gcode") files.push_back(e.path().string());
  }
  std::sort(files.begin(), files.end());
  if (files.empty()) {
    std::fprintf(stderr, "no .gcode files in %s\n", corpus.c_str());
    return 1;
  }
  nlohmann::json json = {{"throughput", nlohmann::json::array()},
                         {"cornering", nlohmann::json::array()}};
  std::printf("Planner throughput (interpreter + lookahead, parsing excluded; median of %d runs)\n", runs);
  std::printf("%-42s %8s %8s %10s %10s %10s %12s %10s %7s\n", "file", "lines", "moves", "Mlines/s", "Mmoves/s",
              "wall_ms", "+joints M/s", "segments", "forced");
  for (size_t fi = 0; fi < files.size(); ++fi) {
    const std::string name = std::filesystem::path(files[fi]).filename().string();
    const Loaded l = load(files[fi]);
    const PlannerConfig cfg = config_for(name);
    std::vector<double> w, wj;
    RunResult r, rj;
    for (int k = 0; k < runs; ++k) {
      r = run(l, cfg, false, false);
      w.push_back(r.wall_s);
      rj = run(l, cfg, true, false);
      wj.push_back(rj.wall_s);
    }
    const double ws = median(w), wjs = median(wj);
    std::printf("%-42s %8ld %8ld %10.2f %10.2f %10.1f %12.2f %10ld %7ld%s\n", name.c_str(), l.lines, r.moves,
                l.lines / ws / 1e6, r.moves / ws / 1e6, ws * 1e3, rj.moves / wjs / 1e6, rj.segments, r.forced,
                r.rejected ? "  (rejected lines!)" : "");
    json["throughput"].push_back({{"file", name},
                                  {"lines", l.lines},
                                  {"moves", r.moves},
                                  {"wall_s", ws},
                                  {"lines_per_s", l.lines / ws},
                                  {"moves_per_s", r.moves / ws},
                                  {"with_joints_moves_per_s", rj.moves / wjs},
                                  {"joint_segments", rj.segments},
                                  {"print_time_s", r.print_time_s},
                                  {"rejected", r.rejected}});
  }

  std::printf("\nCornering policy comparison (junctions between XYZ moves; corner = turn >= 5 deg)\n");
  std::printf("%-28s %-20s %12s %9s %10s %10s %12s %12s\n", "file", "policy", "print_time_s",
              "corners", "mean_mm_s", "min_mm_s", "mean>=45deg", "mean<5deg");
  for (const char* want : {"star_prism_cartesian.gcode", "benchy_cartesian.gcode"}) {
    const std::string path = corpus + "/" + want;
    if (!std::filesystem::exists(path)) continue;
    const Loaded l = load(path);
    for (CorneringPolicy pol :
         {CorneringPolicy::junction_deviation, CorneringPolicy::sharp_corner, CorneringPolicy::speed_change}) {
      PlannerConfig cfg = config_for(want);
      cfg.cornering = pol;  // speed_change at its default 15 mm/s (thesis Sect. 2.2)
      const RunResult r = run(l, cfg, false, true);
      double sum = 0.0, mn = 1e300, sum45 = 0.0, sum_straight = 0.0;
      long n = 0, n45 = 0, n_straight = 0;
      for (const auto& [ang, v] : r.corners) {
        if (ang >= 5.0) {
          sum += v;
          mn = std::min(mn, v);
          ++n;
          if (ang >= 45.0) {
            sum45 += v;
            ++n45;
          }
        } else {
          sum_straight += v;
          ++n_straight;
        }
      }
      const char* pname = pol == CorneringPolicy::junction_deviation ? "junction_deviation"
                          : pol == CorneringPolicy::sharp_corner     ? "sharp_corner_eq67"
                                                                     : "speed_change_15";
      const double mean = n ? sum / n : 0.0, mean45 = n45 ? sum45 / n45 : 0.0, mean_s = n_straight ? sum_straight / n_straight : 0.0;
      std::printf("%-28s %-20s %12.1f %9ld %10.2f %10.3f %12.2f %12.2f\n", want, pname, r.print_time_s, n, mean, n ? mn : 0.0,
                  mean45, mean_s);
      json["cornering"].push_back({{"file", want},
                                   {"policy", pname},
                                   {"print_time_s", r.print_time_s},
                                   {"corners", n},
                                   {"corner_mean_mm_s", mean},
                                   {"corner_min_mm_s", n ? mn : 0.0},
                                   {"corner45_mean_mm_s", mean45},
                                   {"straight_mean_mm_s", mean_s}});
    }
  }
  if (!json_path.empty()) {
    if (!feedloop::bench::write_json(json_path, json)) return 1;
  }
  return 0;
}
