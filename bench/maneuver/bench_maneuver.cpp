// bench_maneuver: Table III of output-maneuvering-cartesian (max and integral of the cross-track
// error and the time) for the three speed assignments of the paper and our arc-length variant.
// First like for like (like_for_like.hpp: one layer of the paper's length, the controller's own
// model beside plants that are not, the magnitude gap one cause at a time, the arc variant tuned
// on generated parts and scored on slicer files), then ten 0.4 mm layers of a part.
//
//   bench_maneuver [--json FILE] [--csv-dir DIR] [--part fin|star]
//                  [--gcode FILE [--feature NAME] [--stride K]] [--dt S] [--speed M_S]
//                  [--servo-period S]
//
// The path is the external perimeter of a maneuver/test_part.hpp part (fin: the paper-like
// default; star: long straight edges into sharp corners) written as G-code and read back through
// the G-code path reader; --gcode takes the first loop of each of 10 layers of another file
// instead (e.g. the corpus star prism with --stride 2 for 0.4 mm between layers).
// Gains: Table II for the paper's three rows. For the arc-length row the gradient gain mu is
// scaled by the mean segment length squared: z^T P b grows with dy_d/dtheta, so with arc-length
// theta the paper's mu = 1000 would be about 1/||Delta||^2 times stronger than with unit theta
// (and makes theta chatter back and forth across a corner); mu ||Delta||^2 keeps it equivalent.
// Three tables: the continuous controller (the paper's setting), the sampled servo (zero-order
// hold) at --servo-period (default 0.2 ms) and at 1 ms, where Table II's gains diverge.
// --csv-dir writes one CSV per scenario of the continuous table:
// time_s,x_m,y_m,z_m,theta,segment,along_m,cross_m, lyapunov,speed_m_s,assigned_m_s.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench/bench_json.hpp"
#include "like_for_like.hpp"
#include "maneuver/controller.hpp"
#include "maneuver/gcode_path.hpp"
#include "maneuver/simulation.hpp"
#include "maneuver/test_part.hpp"

using namespace feedloop::maneuver;

namespace {

struct Scenario {
  const char* name;
  SpeedProfile profile;
  Parameterization param;
  bool split;
};

void write_csv(const std::string& file, const SimResult& r) {
  FILE* f = std::fopen(file.c_str(), "w");
  if (!f) {
    std::fprintf(stderr, "cannot write %s\n", file.c_str());
    return;
  }
  std::fprintf(
      f, "time_s,x_m,y_m,z_m,theta,segment,along_m,cross_m,lyapunov,speed_m_s,assigned_m_s\n");
  for (const SimSample& s : r.samples)
    std::fprintf(f, "%.5f,%.7f,%.7f,%.7f,%.6f,%zu,%.4e,%.4e,%.4e,%.5f,%.5f\n", s.t_s, s.pos_m.x(),
                 s.pos_m.y(), s.pos_m.z(), s.theta, s.segment, s.along_m, s.cross_m, s.lyapunov,
                 s.speed_m_s, s.assigned_m_s);
  std::fclose(f);
}

}  // namespace

int main(int argc, char** argv) {
  std::string json_file, csv_dir, gcode_file, feature = "External perimeter", part = "fin";
  size_t stride = 1;
  double dt_s = 1.0e-4, m_s = 0.1, servo_period_s = 2.0e-4;
  feedloop::bench_maneuver::StudyOptions study;
  bool run_study = true;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has_next = i + 1 < argc;
    if (a == "--json" && has_next)
      json_file = argv[++i];
    else if (a == "--csv-dir" && has_next)
      csv_dir = argv[++i];
    else if (a == "--gcode" && has_next)
      gcode_file = argv[++i];
    else if (a == "--part" && has_next &&
             (std::strcmp(argv[i + 1], "fin") == 0 || std::strcmp(argv[i + 1], "star") == 0))
      part = argv[++i];
    else if (a == "--feature" && has_next)
      feature = argv[++i];
    else if (a == "--stride" && has_next)
      stride = std::strtoul(argv[++i], nullptr, 10);
    else if (a == "--dt" && has_next)
      dt_s = std::atof(argv[++i]);
    else if (a == "--speed" && has_next)
      m_s = std::atof(argv[++i]);
    else if (a == "--servo-period" && has_next)
      servo_period_s = std::atof(argv[++i]);
    else if (a == "--gcode-dir" && has_next)
      study.gcode_dir = argv[++i];
    else if (a == "--offnominal-period" && has_next)
      study.servo_period_s = std::atof(argv[++i]);
    else if (a == "--draws" && has_next)
      study.draws = std::max(1, std::atoi(argv[++i]));
    else if (a == "--quick")
      study.quick = true, study.draws = 2;
    else if (a == "--no-study")
      run_study = false;
    else {
      std::fprintf(
          stderr,
          "usage: bench_maneuver [--json FILE] [--csv-dir DIR] [--part fin|star] [--gcode "
          "FILE [--feature NAME] "
          "[--stride K]] [--dt S] [--speed M_S] [--servo-period S] [--gcode-dir DIR] [--draws N] "
          "[--offnominal-period S] [--quick] [--no-study]\n");
      return 2;
    }
  }

  nlohmann::json json = nlohmann::json::object();
  if (run_study && gcode_file.empty() && part == "fin") {
    if (feedloop::bench_maneuver::run_like_for_like(study, json) != 0) return 1;
    std::printf(
        "\nD. Ten 0.4 mm layers of a part (totals over the ten layers; Table III is per layer: see "
        "A).\n");
  }

  GcodePathOptions gopt;
  gopt.layers = 10;
  gopt.layer_stride = stride;
  gopt.feature = feature;
  TestPartOptions topt;
  topt.part = part == "star" ? TestPart::star : TestPart::fin;
  auto wp_mm = gcode_file.empty()
                   ? extrusion_path_from_gcode(test_part_gcode(topt), "test_part", gopt)
                   : extrusion_path_from_gcode_file(gcode_file, gopt);
  if (!wp_mm) {
    std::fprintf(stderr, "%s\n", wp_mm.error().to_string().c_str());
    return 1;
  }
  std::vector<Vec3> wp_m;
  for (const Vec3& p : *wp_mm) wp_m.push_back(p * 1e-3);  // G-code mm -> model metres

  const Scenario scenarios[] = {
      {"constant", SpeedProfile::constant, Parameterization::unit, false},
      {"every_transition", SpeedProfile::every_transition, Parameterization::unit, false},
      {"sharp_corner", SpeedProfile::sharp_corner, Parameterization::unit, false},
      {"sharp_corner_arc", SpeedProfile::sharp_corner_arc, Parameterization::arc_length, true},
  };
  const CartesianDcPlant plant;
  const ManeuverController ctl_paper(plant, ManeuverGains{});
  SpeedParams sp;
  sp.m_s_m_s = m_s;

  auto probe = PiecewiseLinearPath::create(wp_m, Parameterization::unit);
  if (!probe) {
    std::fprintf(stderr, "%s\n", probe.error().to_string().c_str());
    return 1;
  }
  const double mean_seg_m = probe->length_m() / static_cast<double>(probe->segments());
  ManeuverGains arc_gains;
  arc_gains.mu = ManeuverGains{}.mu * mean_seg_m * mean_seg_m;
  const ManeuverController ctl_arc(plant, arc_gains);
  const std::string path_name =
      gcode_file.empty() ? "maneuver/test_part " + part + " (generated G-code)" : gcode_file;
  std::printf(
      "path: %s, 10 layers, %zu segments, %.1f mm (mean segment %.2f mm); m_s %.3f m/s, dt %.0e "
      "s\n",
      path_name.c_str(), probe->segments(), probe->length_m() * 1e3, mean_seg_m * 1e3, m_s, dt_s);
  std::printf("gains: Table II (arc-length row: mu = %.3g); arc sigmoid a1 %.3f mm, a2 %.4f mm\n",
              arc_gains.mu, sp.a1_m * 1e3, sp.a2_m * 1e3);
  json["bench"] = "maneuver";
  json["path"] = path_name;
  json["m_s_m_s"] = m_s;
  json["dt_s"] = dt_s;
  json["tables"] = nlohmann::json::array();
  auto run_table = [&](double period_s) -> int {
    if (period_s > 0.0)
      std::printf("\nsampled servo at %.0f Hz (zero-order hold; errors at the samples):\n",
                  1.0 / period_s);
    else
      std::printf("\ncontinuous controller (evaluated at every RK4 stage):\n");
    std::printf("%-18s %12s %12s %10s %10s %8s\n", "scenario", "max|e| m", "IAE m*s", "time s",
                "s/layer", "skipped");
    nlohmann::json table = {{"control_period_s", period_s}, {"scenarios", nlohmann::json::array()}};
    for (const Scenario& sc : scenarios) {
      auto path = PiecewiseLinearPath::create(wp_m, sc.param);
      if (!path) {
        std::fprintf(stderr, "%s\n", path.error().to_string().c_str());
        return 1;
      }
      auto speed = SpeedAssignment::create(*path, sc.profile, sp);
      if (!speed) {
        std::fprintf(stderr, "%s\n", speed.error().to_string().c_str());
        return 1;
      }
      SimOptions so;
      so.dt_s = dt_s;
      so.split_at_waypoints = sc.split;
      so.record_every = csv_dir.empty() || period_s > 0.0 ? 0 : 10;
      so.control_period_s = period_s;
      auto r = simulate(*path, *speed, sc.param == Parameterization::unit ? ctl_paper : ctl_arc,
                        plant, so);
      if (!r) {
        std::printf("%-18s %s\n", sc.name, r.error().to_string().c_str());
        continue;
      }
      char line[400];
      std::snprintf(line, sizeof line, "%-18s %12.3e %12.3e %10.3f %10.3f %8zu", sc.name,
                    r->max_cross_m, r->iae_cross_m_s, r->total_time_s, r->total_time_s / 10.0,
                    r->skipped_segments);
      std::printf("%s%s\n", line, r->finished ? "" : "  NOT FINISHED");
      table["scenarios"].push_back({{"name", sc.name},
                                    {"max_cross_m", r->max_cross_m},
                                    {"iae_cross_m_s", r->iae_cross_m_s},
                                    {"total_time_s", r->total_time_s},
                                    {"time_per_layer_s", r->total_time_s / 10.0},
                                    {"max_along_m", r->max_along_m},
                                    {"skipped_segments", r->skipped_segments},
                                    {"finished", r->finished}});
      if (!csv_dir.empty() && period_s == 0.0)
        write_csv(csv_dir + "/maneuver_" + sc.name + ".csv", *r);
    }
    json["tables"].push_back(std::move(table));
    return 0;
  };
  for (double period_s : {0.0, servo_period_s, 1e-3})
    if (run_table(period_s) != 0) return 1;
  if (!json_file.empty()) {
    if (!feedloop::bench::write_json(json_file, json)) return 1;
  }
  return 0;
}
