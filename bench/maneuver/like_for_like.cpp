// Like for like (issue 19); see like_for_like.hpp and README.md.
#include "like_for_like.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "maneuver/controller.hpp"
#include "maneuver/corner_response.hpp"
#include "maneuver/gcode_path.hpp"
#include "maneuver/offnominal_plant.hpp"
#include "maneuver/simulation.hpp"
#include "maneuver/test_part.hpp"

namespace feedloop::bench_maneuver {

using namespace feedloop::maneuver;
using nlohmann::json;

namespace {

// Table III of the paper: ||e||_inf, IAE, time for one layer of its part.
struct PaperRow {
  SpeedProfile profile;
  double max_m, iae_m_s, time_s;  // 0: not in the paper
};
constexpr PaperRow kPaper[] = {
    {SpeedProfile::constant, 1.92e-2, 1.82e-3, 2.42},
    {SpeedProfile::every_transition, 5.80e-4, 5.76e-5, 6.11},
    {SpeedProfile::sharp_corner, 9.54e-3, 1.26e-3, 2.57},
    {SpeedProfile::sharp_corner_arc, 0.0, 0.0, 0.0},
};
constexpr double kPaperLayerMm = 242.0;  // 2.42 s at m_s = 0.1 m/s

// How a row is run.
struct Setting {
  double period_s = 0.0;  // 0: continuous controller (RK4 over plant + controller)
  double dt_s = 1.0e-4;   // RK4 step (continuous) or substep bound (nominal sampled)
  const OffNominalParams* plant = nullptr;  // null: the controller's own model, measured exactly
  bool as_printed = false;                  // Eq. 57/58 as printed
  double mu_arc = 0.0;          // > 0: the arc row's mu; 0: Table II's mu x (mean segment)^2
  double k_d = 0.0, k_p = 0.0;  // > 0: instead of Table II's
};

struct Figures {
  bool ok = false;
  std::string error;
  double max_m = 0.0, iae_m_s = 0.0, time_s = 0.0, limited = 0.0;
  size_t skipped = 0;
};

Figures run(const std::vector<Vec3>& wp_m, SpeedProfile prof, const SpeedParams& sp,
            const Setting& st) {
  Figures f;
  const bool arc = prof == SpeedProfile::sharp_corner_arc;
  auto path = PiecewiseLinearPath::create(
      wp_m, arc ? Parameterization::arc_length : Parameterization::unit);
  if (!path) return f.error = path.error().to_string(), f;
  auto speed = SpeedAssignment::create(*path, prof, sp);
  if (!speed) return f.error = speed.error().to_string(), f;
  const CartesianDcPlant nominal;  // Table I: the controller's model in every row
  ManeuverGains g;
  g.as_printed = st.as_printed;
  if (st.k_d > 0.0) g.k_d = st.k_d;
  if (st.k_p > 0.0) g.k_p = st.k_p;
  // Arc length: mu scaled by the mean segment length squared (docs/maneuver.md).
  const double mean_seg_m = path->length_m() / static_cast<double>(path->segments());
  if (arc) g.mu = st.mu_arc > 0.0 ? st.mu_arc : g.mu * mean_seg_m * mean_seg_m;
  const ManeuverController ctl(nominal, g);
  SimOptions so;
  so.dt_s = st.dt_s;
  so.split_at_waypoints = arc;
  so.record_every = 0;
  so.control_period_s = st.period_s;
  so.max_time_s = 40.0 * path->length_m() / sp.m_s_m_s + 10.0;
  Result<SimResult> r = Error{"", {}};
  if (st.plant) {
    OffNominalPlant plant(*st.plant);
    r = simulate_sampled(*path, *speed, ctl, plant, so);
  } else {
    r = simulate(*path, *speed, ctl, nominal, so);
  }
  if (!r) return f.error = r.error().to_string(), f;
  if (!r->finished) return f.error = "did not finish", f;
  f.ok = true;
  f.max_m = r->max_cross_m;
  f.iae_m_s = r->iae_cross_m_s;
  f.time_s = r->total_time_s;
  f.limited = r->limited_fraction;
  f.skipped = r->skipped_segments;
  return f;
}

Result<std::vector<Vec3>> part_path(TestPart part, int layers, double layer_length_mm) {
  TestPartOptions tp;
  tp.part = part;
  tp.layers = layers;
  tp.layer_length_mm = layer_length_mm;
  GcodePathOptions gp;
  gp.layers = static_cast<size_t>(layers);
  gp.feature = "External perimeter";
  auto wp = extrusion_path_from_gcode(test_part_gcode(tp), "test_part", gp);
  if (!wp) return wp.error();
  std::vector<Vec3> m;
  for (const Vec3& p : *wp) m.push_back(p * 1e-3);
  return m;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n == 0 ? 0.0 : (n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]));
}

// The median figures over the off-nominal draws (seeds 1..draws), and the worst max.
struct DrawFigures {
  Figures median;
  double worst_max_m = 0.0;
  int failed = 0;
};

DrawFigures over_draws(const std::vector<Vec3>& wp_m, SpeedProfile prof, const SpeedParams& sp,
                       double period_s, int draws,
                       const std::function<OffNominalParams(uint64_t)>& machine,
                       double mu_arc = 0.0, double k_d = 0.0, double k_p = 0.0) {
  std::vector<double> mx, iae, t, lim;
  DrawFigures d;
  for (int s = 1; s <= draws; ++s) {
    const OffNominalParams p = machine(static_cast<uint64_t>(s));
    Setting st;
    st.period_s = period_s;
    st.plant = &p;
    st.mu_arc = mu_arc;
    st.k_d = k_d;
    st.k_p = k_p;
    const Figures f = run(wp_m, prof, sp, st);
    if (!f.ok) {
      ++d.failed;
      d.median.error = f.error;
      continue;
    }
    mx.push_back(f.max_m);
    iae.push_back(f.iae_m_s);
    t.push_back(f.time_s);
    lim.push_back(f.limited);
    d.worst_max_m = std::max(d.worst_max_m, f.max_m);
  }
  if (!mx.empty()) {
    d.median.ok = true;
    d.median.max_m = median(mx);
    d.median.iae_m_s = median(iae);
    d.median.time_s = median(t);
    d.median.limited = median(lim);
  }
  return d;
}

std::string fmt(double v, const char* f = "%.3e") {
  char b[32];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

// Table A: Table III like for like.
int table_iii(const StudyOptions& o, const std::vector<Vec3>& layer, json& out) {
  SpeedParams sp;
  std::printf(
      "\nA. Table III like for like: one layer of the fin part scaled to the paper's %.0f mm, m_s "
      "0.1 m/s, "
      "e of Eq. 70 in metres, IAE in m*s over the layer, the layer's time.\n"
      "   nominal: the controller's own model (Table I), continuous controller, RK4 1e-4 s.\n"
      "   off-nominal: %d drawn machines (draw_offnominal, seeds 1..%d: belt, Stribeck friction, "
      "motor L, "
      "24 V / 40 N limits, masses and motor constants off, 0.96 um motor encoder read after 10-60 "
      "us, "
      "velocity differenced and filtered at 2 kHz), servo at %.0f Hz, K_d %.0f/s K_p %.0f/s (Table "
      "II's chatter, "
      "see B): median (worst max), and the share of periods at a drive limit.\n",
      kPaperLayerMm, o.draws, o.draws, 1.0 / o.servo_period_s, o.k_d_offnominal, o.k_p_offnominal);
  std::printf("%-17s | %9s %9s %6s | %9s %9s %6s | %9s %9s %9s %6s %6s\n", "row", "paper max",
              "paper IAE", "time", "nom max", "nom IAE", "time", "off max", "(worst)", "off IAE",
              "time", "limit");
  out["table_iii"] = json::array();
  for (const PaperRow& pr : kPaper) {
    const Figures nom = run(layer, pr.profile, sp, Setting{});
    const DrawFigures off = over_draws(
        layer, pr.profile, sp, o.servo_period_s, o.draws,
        [](uint64_t s) { return draw_offnominal(s); }, 0.0, o.k_d_offnominal, o.k_p_offnominal);
    if (!nom.ok) {
      std::printf("%-17s nominal: %s\n", to_string(pr.profile), nom.error.c_str());
      return 1;
    }
    std::printf(
        "%-17s | %9s %9s %6s | %9.2e %9.2e %6.2f | %9s %9s %9s %6s %5.1f%%%s\n",
        to_string(pr.profile), pr.time_s > 0 ? fmt(pr.max_m, "%.2e").c_str() : "-",
        pr.time_s > 0 ? fmt(pr.iae_m_s, "%.2e").c_str() : "-",
        pr.time_s > 0 ? fmt(pr.time_s, "%.2f").c_str() : "-", nom.max_m, nom.iae_m_s, nom.time_s,
        off.median.ok ? fmt(off.median.max_m, "%.2e").c_str() : "failed",
        off.median.ok ? ("(" + fmt(off.worst_max_m, "%.2e") + ")").c_str() : "",
        off.median.ok ? fmt(off.median.iae_m_s, "%.2e").c_str() : "",
        off.median.ok ? fmt(off.median.time_s, "%.2f").c_str() : "", 100.0 * off.median.limited,
        off.failed
            ? ("  " + std::to_string(off.failed) + " draw(s) failed: " + off.median.error).c_str()
            : "");
    json row = {
        {"name", to_string(pr.profile)},
        {"nominal",
         {{"max_cross_m", nom.max_m}, {"iae_cross_m_s", nom.iae_m_s}, {"time_s", nom.time_s}}},
        {"offnominal_median",
         {{"max_cross_m", off.median.max_m},
          {"iae_cross_m_s", off.median.iae_m_s},
          {"time_s", off.median.time_s},
          {"limited_fraction", off.median.limited},
          {"worst_max_cross_m", off.worst_max_m},
          {"failed_draws", off.failed}}}};
    if (pr.time_s > 0)
      row["paper"] = {
          {"max_cross_m", pr.max_m}, {"iae_cross_m_s", pr.iae_m_s}, {"time_s", pr.time_s}};
    out["table_iii"].push_back(row);
  }
  return 0;
}

// Table B: the magnitude gap, one condition at a time, for the constant and sharp-corner rows.
int gap_table(const StudyOptions& o, const std::vector<Vec3>& layer, json& out) {
  SpeedParams sp;
  const OffNominalParams drawn = draw_offnominal(1);
  auto only = [&](const std::function<void(OffNominalParams&)>& set) {
    OffNominalParams p;  // everything nominal and exact...
    set(p);              // ...but this group, at draw 1's size
    return p;
  };
  struct Condition {
    std::string name;
    std::function<Figures(SpeedProfile)> run;
  };
  auto ten_layers = part_path(TestPart::fin, 10, kPaperLayerMm);
  auto small_part = part_path(TestPart::fin, 1, 0.0);
  if (!ten_layers || !small_part) {
    std::printf("B: %s\n",
                (!ten_layers ? ten_layers.error() : small_part.error()).to_string().c_str());
    return 1;
  }
  std::vector<OffNominalParams> groups;
  const std::vector<std::pair<std::string, std::function<void(OffNominalParams&)>>> group_defs = {
      {"masses, J_m, B, K_m, R_a off",
       [&](OffNominalParams& p) {
         p.mass_scale = drawn.mass_scale;
         p.motor_inertia_scale = drawn.motor_inertia_scale;
         p.viscous_scale = drawn.viscous_scale;
         p.torque_constant_scale = drawn.torque_constant_scale;
         p.resistance_scale = drawn.resistance_scale;
       }},
      {"motor L and back-EMF",
       [&](OffNominalParams& p) {
         p.back_emf = drawn.back_emf;
         p.electrical_time_constant_s = drawn.electrical_time_constant_s;
       }},
      {"24 V / 40 N limits",
       [&](OffNominalParams& p) {
         p.voltage_limit_v = drawn.voltage_limit_v;
         p.force_limit_n = drawn.force_limit_n;
       }},
      {"belt compliance",
       [&](OffNominalParams& p) {
         p.belt_stiffness_n_m = drawn.belt_stiffness_n_m;
         p.belt_damping_ratio = drawn.belt_damping_ratio;
       }},
      {"Stribeck friction",
       [&](OffNominalParams& p) {
         p.coulomb_n = drawn.coulomb_n;
         p.static_n = drawn.static_n;
         p.stribeck_velocity_m_s = drawn.stribeck_velocity_m_s;
       }},
      {"encoder, delay, differenced v",
       [&](OffNominalParams& p) {
         p.encoder_resolution_m = drawn.encoder_resolution_m;
         p.measurement_delay_s = drawn.measurement_delay_s;
         p.differenced_velocity = drawn.differenced_velocity;
         p.velocity_filter_hz = drawn.velocity_filter_hz;
       }},
  };
  groups.reserve(group_defs.size());
  for (const auto& gd : group_defs) groups.push_back(only(gd.second));

  std::vector<Condition> conds;
  conds.push_back({"baseline: nominal, continuous, 1 layer",
                   [&](SpeedProfile p) { return run(layer, p, sp, Setting{}); }});
  conds.push_back({"ten layers (IAE summed)",
                   [&](SpeedProfile p) { return run(*ten_layers, p, sp, Setting{}); }});
  conds.push_back({"our earlier 180 mm part",
                   [&](SpeedProfile p) { return run(*small_part, p, sp, Setting{}); }});
  conds.push_back({"Eq. 57/58 as printed", [&](SpeedProfile p) {
                     Setting st;
                     st.as_printed = true;
                     return run(layer, p, sp, st);
                   }});
  conds.push_back({"fixed step 1 ms (paper's stepping)", [&](SpeedProfile p) {
                     Setting st;
                     st.dt_s = 1e-3;
                     return run(layer, p, sp, st);
                   }});
  conds.push_back({"sampled servo (ZOH)", [&](SpeedProfile p) {
                     Setting st;
                     st.period_s = o.servo_period_s;
                     return run(layer, p, sp, st);
                   }});
  for (size_t i = 0; i < groups.size(); ++i)
    conds.push_back({"plant: " + group_defs[i].first, [&, i](SpeedProfile p) {
                       Setting st;
                       st.period_s = o.servo_period_s;
                       st.plant = &groups[i];
                       return run(layer, p, sp, st);
                     }});
  conds.push_back({"plant: all effects, Table II gains", [&](SpeedProfile p) {
                     return over_draws(layer, p, sp, o.servo_period_s, o.draws,
                                       [](uint64_t s) { return draw_offnominal(s); })
                         .median;
                   }});
  conds.push_back({"plant: all effects, K_d " + fmt(o.k_d_offnominal, "%.0f") + " K_p " +
                       fmt(o.k_p_offnominal, "%.0f"),
                   [&](SpeedProfile p) {
                     return over_draws(
                                layer, p, sp, o.servo_period_s, o.draws,
                                [](uint64_t s) { return draw_offnominal(s); }, 0.0,
                                o.k_d_offnominal, o.k_p_offnominal)
                         .median;
                   }});

  std::printf(
      "\nB. The magnitude gap, one condition at a time (each row changes one thing from the "
      "baseline; x: "
      "factor against the baseline; draw 1's sizes: %s)\n",
      drawn.describe().c_str());
  std::printf("%-44s | %9s %7s %9s %7s | %9s %7s %9s %7s %6s\n",
              "condition (servo 20 kHz where sampled)", "const max", "x", "const IAE", "x",
              "sharp max", "x", "sharp IAE", "x", "limit");
  out["gap"] = json::array();
  Figures base_c, base_s;
  for (size_t i = 0; i < conds.size(); ++i) {
    const Figures c = conds[i].run(SpeedProfile::constant);
    const Figures s = conds[i].run(SpeedProfile::sharp_corner);
    if (i == 0) {
      base_c = c;
      base_s = s;
    }
    auto cell = [](const Figures& f, double v, double base) {
      return f.ok ? fmt(v, "%9.2e") + " " + fmt(v / base, "%7.2f")
                  : std::string("   failed        ");
    };
    std::printf("%-44s | %s %s | %s %s %5.1f%%\n", conds[i].name.c_str(),
                cell(c, c.max_m, base_c.max_m).c_str(), cell(c, c.iae_m_s, base_c.iae_m_s).c_str(),
                cell(s, s.max_m, base_s.max_m).c_str(), cell(s, s.iae_m_s, base_s.iae_m_s).c_str(),
                100.0 * s.limited);
    if (!c.ok) std::printf("    constant: %s\n", c.error.c_str());
    if (!s.ok) std::printf("    sharp_corner: %s\n", s.error.c_str());
    out["gap"].push_back(
        {{"condition", conds[i].name},
         {"constant", {{"ok", c.ok}, {"max_cross_m", c.max_m}, {"iae_cross_m_s", c.iae_m_s}}},
         {"sharp_corner",
          {{"ok", s.ok},
           {"max_cross_m", s.max_m},
           {"iae_cross_m_s", s.iae_m_s},
           {"limited_fraction", s.limited}}}});
  }
  std::printf("%-44s | %9.2e %7.0f %9.2e %7.0f | %9.2e %7.0f %9.2e %7.0f\n", "paper (Table III)",
              kPaper[0].max_m, kPaper[0].max_m / base_c.max_m, kPaper[0].iae_m_s,
              kPaper[0].iae_m_s / base_c.iae_m_s, kPaper[2].max_m, kPaper[2].max_m / base_s.max_m,
              kPaper[2].iae_m_s, kPaper[2].iae_m_s / base_s.iae_m_s);
  std::printf("%-44s | %9.2e %7.2f %9.2e %7.2f | %9.2e %7.2f %9.2e %7.2f\n",
              "paper read in mm (x 1e-3)", kPaper[0].max_m * 1e-3,
              kPaper[0].max_m * 1e-3 / base_c.max_m, kPaper[0].iae_m_s * 1e-3,
              kPaper[0].iae_m_s * 1e-3 / base_c.iae_m_s, kPaper[2].max_m * 1e-3,
              kPaper[2].max_m * 1e-3 / base_s.max_m, kPaper[2].iae_m_s * 1e-3,
              kPaper[2].iae_m_s * 1e-3 / base_s.iae_m_s);
  // The ratio the units cannot change: constant over every-transition, ours and the paper's.
  const Figures et = run(layer, SpeedProfile::every_transition, sp, Setting{});
  std::printf(
      "constant / every_transition max: ours %.1f, paper %.1f; constant / sharp_corner max: ours "
      "%.1f, paper %.1f\n",
      base_c.max_m / et.max_m, kPaper[0].max_m / kPaper[1].max_m, base_c.max_m / base_s.max_m,
      kPaper[0].max_m / kPaper[2].max_m);
  // The paper's stepping on slicer output: unit theta and a fixed step skip segments shorter than
  // m_s dt (Sect. V-A); our part has none, slicer files have them.
  std::printf(
      "fixed-step stepping on slicer paths (nominal, continuous; factor against dt 1e-4 s on the "
      "same path):\n");
  out["stepping"] = json::array();
  for (const char* file : {"star_prism_cartesian.gcode", "circles_plate_cartesian.gcode"}) {
    GcodePathOptions gp;
    gp.layers = 1;
    gp.feature = "External perimeter";
    auto wp = extrusion_path_from_gcode_file(o.gcode_dir + "/" + file, gp);
    if (!wp) {
      std::printf("  %s: %s (not measured)\n", file, wp.error().to_string().c_str());
      continue;
    }
    std::vector<Vec3> wp_m;
    for (const Vec3& q : *wp) wp_m.push_back(q * 1e-3);
    for (SpeedProfile prof : {SpeedProfile::constant, SpeedProfile::sharp_corner}) {
      Figures f[3];
      const double dts[3] = {1e-4, 1e-3, 1.5e-3};  // 1.5 ms: K_d dt 2.5, inside RK4's 2.78
      std::printf("  %-30s %-13s", file, to_string(prof));
      for (int k = 0; k < 3; ++k) {
        Setting st;
        st.dt_s = dts[k];
        f[k] = run(wp_m, prof, sp, st);
        if (f[k].ok)
          std::printf(" | dt %.1e: max %.2e (x%.1f) IAE %.2e (x%.1f) skipped %zu", dts[k],
                      f[k].max_m, f[k].max_m / f[0].max_m, f[k].iae_m_s,
                      f[k].iae_m_s / f[0].iae_m_s, f[k].skipped);
        else
          std::printf(" | dt %.1e: %s", dts[k], f[k].error.c_str());
        out["stepping"].push_back({{"file", file},
                                   {"row", to_string(prof)},
                                   {"dt_s", dts[k]},
                                   {"ok", f[k].ok},
                                   {"max_cross_m", f[k].max_m},
                                   {"iae_cross_m_s", f[k].iae_m_s},
                                   {"skipped", f[k].skipped}});
      }
      std::printf("\n");
    }
  }
  // The gain ladder behind k_d_offnominal: sharp_corner on draw 1, all effects.
  std::printf("gain ladder on draw 1 (all effects, sharp_corner; K_p = 0.3 K_d):");
  out["gain_ladder"] = json::array();
  for (double kd : {100.0, 200.0, 400.0, 800.0, 1667.0}) {
    const OffNominalParams m1 = draw_offnominal(1);
    Setting st;
    st.period_s = o.servo_period_s;
    st.plant = &m1;
    st.k_d = kd;
    st.k_p = 0.3 * kd;
    const Figures f = run(layer, SpeedProfile::sharp_corner, sp, st);
    std::printf("  K_d %.0f: max %s, limit %.1f%%", kd,
                f.ok ? fmt(f.max_m, "%.2e").c_str() : "failed", 100.0 * f.limited);
    out["gain_ladder"].push_back(
        {{"k_d", kd}, {"ok", f.ok}, {"max_cross_m", f.max_m}, {"limited_fraction", f.limited}});
  }
  std::printf("\n");
  out["ratios"] = {{"constant_over_every_transition_ours", base_c.max_m / et.max_m},
                   {"constant_over_every_transition_paper", kPaper[0].max_m / kPaper[1].max_m},
                   {"constant_over_sharp_corner_ours", base_c.max_m / base_s.max_m},
                   {"constant_over_sharp_corner_paper", kPaper[0].max_m / kPaper[2].max_m}};
  return 0;
}

// Table E: one corner at a time on the controller's own model (Table I/II, continuous). The
// closed loop with the exact model is linear in z (Eq. 55), so a corner's error is its turn's
// velocity jump times one response: the largest error any corner can cause at m_s, and how long
// it lasts, bound what a layer can show; the paper's figures are then read as counts of corners.
int corner_table(json& out) {
  SpeedParams sp;
  std::printf(
      "\nE. One corner at a time on the controller's own model (Table I/II, continuous, RK4 1e-4 "
      "s, m_s %.1f m/s, 30 mm legs):\n"
      "   the largest cross-track error e (Eq. 70), the largest |z_1| (along and cross, the start "
      "from rest included), the IAE of e and the time from the corner until "
      "|e| stays below 1 %% of its peak.\n",
      sp.m_s_m_s);
  std::printf("%-9s | %9s %9s %9s %8s | %9s %9s %9s %8s\n", "turn deg", "const e", "|z_1|", "IAE",
              "settle", "sharp e", "|z_1|", "IAE", "settle");
  out["corners"] = json::array();
  CornerResponse worst_z1, c90;
  for (double turn : {5.0, 10.0, 15.0, 20.0, 30.0, 45.0, 90.0, 135.0, 175.0}) {
    const auto cr = corner_response(corner_path(turn, 1, 0.0), SpeedProfile::constant, sp);
    const auto sr = corner_response(corner_path(turn, 1, 0.0), SpeedProfile::sharp_corner, sp);
    if (!cr || !sr) {
      std::printf("E: %.0f deg: %s\n", turn, (!cr ? cr.error() : sr.error()).to_string().c_str());
      return 1;
    }
    const CornerResponse &c = *cr, &s = *sr;
    std::printf("%-9.0f | %9.2e %9.2e %9.2e %5.1f ms | %9.2e %9.2e %9.2e %5.1f ms\n", turn,
                c.max_cross_m, c.max_z1_m, c.iae_cross_m_s, 1e3 * c.settle_s, s.max_cross_m,
                s.max_z1_m, s.iae_cross_m_s, 1e3 * s.settle_s);
    auto fig = [](const CornerResponse& x) {
      return json{{"max_cross_m", x.max_cross_m},
                  {"max_z1_m", x.max_z1_m},
                  {"iae_cross_m_s", x.iae_cross_m_s},
                  {"settle_s", x.settle_s}};
    };
    out["corners"].push_back({{"turn_deg", turn}, {"constant", fig(c)}, {"sharp_corner", fig(s)}});
    if (c.max_z1_m > worst_z1.max_z1_m) worst_z1 = c;
    if (turn == 90.0) c90 = c;
  }
  // What the paper's constant row means in corners, read in metres and in millimetres.
  const double reach_mm = 1e3 * sp.m_s_m_s * worst_z1.settle_s;
  const PaperRow& pc = kPaper[0];
  std::printf(
      "Any corner: |e| <= |z_1| <= %.2e m, gone within %.1f ms (%.2f mm of path at m_s). The "
      "paper's constant row,\n"
      "   in metres: max %.2e m = %.0f of the worst corners superposed within %.2f mm of path; IAE "
      "%.2e m*s = %.0f 90-degree corners in one layer;\n"
      "   in millimetres: max %.2e m = %.2f x one 90-degree corner's %.2e m; IAE %.2e m*s = %.1f "
      "90-degree corners (or %.0f 5-degree chord turns).\n",
      worst_z1.max_z1_m, 1e3 * worst_z1.settle_s, reach_mm, pc.max_m, pc.max_m / worst_z1.max_z1_m,
      reach_mm, pc.iae_m_s, pc.iae_m_s / c90.iae_cross_m_s, 1e-3 * pc.max_m,
      1e-3 * pc.max_m / c90.max_cross_m, c90.max_cross_m, 1e-3 * pc.iae_m_s,
      1e-3 * pc.iae_m_s / c90.iae_cross_m_s,
      1e-3 * pc.iae_m_s / out["corners"][0]["constant"]["iae_cross_m_s"].get<double>());
  // The paper names its part's two 90-degree turns as the constant row's spikes; a slicer rounds
  // such a turn into chords.
  std::printf("A 90-degree turn rounded in chords (max e, constant / sharp-corner):\n");
  out["rounded_90"] = json::array();
  for (int chords : {2, 3, 4}) {
    std::printf("  %d turns of %4.1f deg:", chords, 90.0 / chords);
    for (double chord_mm : {0.1, 0.2, 0.4, 0.8}) {
      const auto wp = corner_path(90.0, chords, 1e-3 * chord_mm);
      const auto cr = corner_response(wp, SpeedProfile::constant, sp);
      const auto sr = corner_response(wp, SpeedProfile::sharp_corner, sp);
      if (!cr || !sr) {
        std::printf("\nE: rounded 90: %s\n", (!cr ? cr.error() : sr.error()).to_string().c_str());
        return 1;
      }
      const CornerResponse &c = *cr, &s = *sr;
      std::printf("  %.1f mm chords %.2e / %.2e", chord_mm, c.max_cross_m, s.max_cross_m);
      out["rounded_90"].push_back({{"turns", chords},
                                   {"chord_mm", chord_mm},
                                   {"constant_max_cross_m", c.max_cross_m},
                                   {"sharp_corner_max_cross_m", s.max_cross_m}});
    }
    std::printf("\n");
  }
  out["corner_reading"] = {{"worst_corner_z1_m", worst_z1.max_z1_m},
                           {"settle_s", worst_z1.settle_s},
                           {"metres_worst_corners_superposed", pc.max_m / worst_z1.max_z1_m},
                           {"metres_90deg_corners_for_iae", pc.iae_m_s / c90.iae_cross_m_s},
                           {"mm_max_over_90deg_corner", 1e-3 * pc.max_m / c90.max_cross_m},
                           {"mm_90deg_corners_for_iae", 1e-3 * pc.iae_m_s / c90.iae_cross_m_s}};
  return 0;
}

// Table C: the arc variant's a1/a2 tuned on generated parts, scored on the corpus.
int held_out(const StudyOptions& o, json& out) {
  SpeedParams base;
  struct Part {
    std::string name;
    std::vector<Vec3> wp_m;
  };
  std::vector<Part> train;
  for (TestPart tp : {TestPart::fin, TestPart::star}) {
    auto wp = part_path(tp, 1, tp == TestPart::fin ? kPaperLayerMm : 0.0);
    if (!wp) {
      std::printf("C: %s\n", wp.error().to_string().c_str());
      return 1;
    }
    train.push_back({tp == TestPart::fin ? "fin (242 mm)" : "star", *wp});
  }
  const int draws = std::max(1, o.draws / 2);
  auto machine = [](uint64_t s) { return draw_offnominal(s + 100); };  // other machines than A's
  // The arc row's mu, fixed from the training parts (not from the part under test).
  double seg_sum_m = 0.0;
  for (const Part& p : train) {
    double len = 0.0;
    for (size_t i = 1; i < p.wp_m.size(); ++i) len += (p.wp_m[i] - p.wp_m[i - 1]).norm();
    seg_sum_m += len / static_cast<double>(p.wp_m.size() - 1);
  }
  const double mean_seg_m = seg_sum_m / static_cast<double>(train.size());
  const double mu_arc = ManeuverGains{}.mu * mean_seg_m * mean_seg_m;
  auto score = [&](const std::vector<Vec3>& wp, SpeedProfile prof, const SpeedParams& sp) {
    return over_draws(wp, prof, sp, o.servo_period_s, draws, machine, mu_arc, o.k_d_offnominal,
                      o.k_p_offnominal)
        .median;
  };

  std::printf(
      "\nC. The arc-length variant against Eq. 67, tuned on generated parts (fin, star), scored on "
      "the corpus's "
      "slicer files (external perimeters), on the off-nominal plant with its 24 V / 40 N limits, "
      "servo %.0f Hz, "
      "median of %d drawn machines (seeds 101..%d).\n",
      1.0 / o.servo_period_s, draws, 100 + draws);
  // Tuning: minimise the mean over the training parts of max/max_67 + IAE/IAE_67 + time/time_67.
  std::vector<Figures> eq67_train;
  for (const Part& p : train) eq67_train.push_back(score(p.wp_m, SpeedProfile::sharp_corner, base));
  const double a1_mm[] = {0.015, 0.03, 0.06, 0.12, 0.25, 0.5, 1.0};
  const double ratio[] = {6.0, 12.0, 24.0};
  double best_cost = 1e300, best_a1 = 0.0, best_a2 = 0.0;
  out["tuning"] = json::array();
  for (double a1 : a1_mm)
    for (double q : ratio) {
      SpeedParams sp = base;
      sp.a1_m = a1 * 1e-3;
      sp.a2_m = a1 * 1e-3 / q;
      sp.reach_m = std::max(base.reach_m, 8.0 * sp.a1_m);
      double cost = 0.0;
      bool ok = true;
      for (size_t i = 0; i < train.size(); ++i) {
        const Figures f = score(train[i].wp_m, SpeedProfile::sharp_corner_arc, sp);
        if (!f.ok || !eq67_train[i].ok) {
          ok = false;
          break;
        }
        cost += f.max_m / eq67_train[i].max_m + f.iae_m_s / eq67_train[i].iae_m_s +
                f.time_s / eq67_train[i].time_s;
      }
      cost = ok ? cost / static_cast<double>(train.size()) : 1e300;
      out["tuning"].push_back({{"a1_mm", a1}, {"a2_mm", a1 / q}, {"cost", ok ? cost : -1.0}});
      if (cost < best_cost) {
        best_cost = cost;
        best_a1 = sp.a1_m;
        best_a2 = sp.a2_m;
      }
    }
  if (best_a1 == 0.0) {
    std::printf("C: no a1/a2 finished on the training parts\n");
    return 1;
  }
  SpeedParams tuned = base;
  tuned.a1_m = best_a1;
  tuned.a2_m = best_a2;
  tuned.reach_m = std::max(base.reach_m, 8.0 * best_a1);
  std::printf(
      "tuned on the training parts: a1 %.3f mm, a2 %.4f mm (cost %.3f; 3.0 = Eq. 67's figures), mu "
      "%.3g (Table II's "
      "x the training parts' mean segment %.2f mm, squared)\n",
      best_a1 * 1e3, best_a2 * 1e3, best_cost, mu_arc, mean_seg_m * 1e3);
  out["tuned"] = {
      {"a1_mm", best_a1 * 1e3}, {"a2_mm", best_a2 * 1e3}, {"cost", best_cost}, {"mu", mu_arc}};

  struct Held {
    const char* file;
    size_t first_layer, layers, stride;
  };
  const Held held[] = {{"star_prism_cartesian.gcode", 0, 5, 5},
                       {"cube20_cartesian.gcode", 0, 5, 5},
                       {"circles_plate_cartesian.gcode", 0, 3, 5},
                       {"benchy_cartesian.gcode", 2, 5, 10},
                       {"vase_cylinder_cartesian.gcode", 0, 1, 1}};
  std::string rows_iii;  // Table III's other two rows on the same parts, printed after
  std::printf("%-30s %6s | %9s %9s %7s | %9s %9s %7s | %7s %7s %7s\n", "held-out part (layers)",
              "mm", "Eq67 max", "Eq67 IAE", "time", "arc max", "arc IAE", "time", "max x", "IAE x",
              "time x");
  out["held_out"] = json::array();
  int scored = 0, arc_better = 0;
  for (const Held& h : held) {
    const std::string file = o.gcode_dir + "/" + h.file;
    if (!std::filesystem::exists(file)) {
      std::printf("%-30s not found in %s: not measured\n", h.file, o.gcode_dir.c_str());
      continue;
    }
    GcodePathOptions gp;
    gp.first_layer = h.first_layer;
    gp.layers = o.quick ? 1 : h.layers;
    gp.layer_stride = h.stride;
    gp.feature = "External perimeter";
    auto wp = extrusion_path_from_gcode_file(file, gp);
    if (!wp) {
      std::printf("%-30s %s\n", h.file, wp.error().to_string().c_str());
      continue;
    }
    std::vector<Vec3> wp_m;
    for (const Vec3& p : *wp) wp_m.push_back(p * 1e-3);
    double len = 0.0;
    for (size_t i = 1; i < wp_m.size(); ++i) len += (wp_m[i] - wp_m[i - 1]).norm();
    const Figures e67 = score(wp_m, SpeedProfile::sharp_corner, base);
    const Figures arc = score(wp_m, SpeedProfile::sharp_corner_arc, tuned);
    const Figures cs = score(wp_m, SpeedProfile::constant, base);
    const Figures et = score(wp_m, SpeedProfile::every_transition, base);
    char name[64];
    std::snprintf(name, sizeof name, "%s (%zu)", h.file, gp.layers);
    {
      char line[256];
      std::snprintf(line, sizeof line, "%-30s | %9s %9s %7s | %9s %9s %7s\n", name,
                    cs.ok ? fmt(cs.max_m, "%.2e").c_str() : "failed",
                    cs.ok ? fmt(cs.iae_m_s, "%.2e").c_str() : "",
                    cs.ok ? fmt(cs.time_s, "%.2f").c_str() : "",
                    et.ok ? fmt(et.max_m, "%.2e").c_str() : "failed",
                    et.ok ? fmt(et.iae_m_s, "%.2e").c_str() : "",
                    et.ok ? fmt(et.time_s, "%.2f").c_str() : "");
      rows_iii += line;
    }
    if (!e67.ok || !arc.ok) {
      std::printf("%-30s failed: %s\n", name, (!e67.ok ? e67.error : arc.error).c_str());
      continue;
    }
    ++scored;
    const bool better =
        arc.max_m <= e67.max_m && arc.iae_m_s <= e67.iae_m_s && arc.time_s <= e67.time_s;
    arc_better += better ? 1 : 0;
    std::printf("%-30s %6.0f | %9.2e %9.2e %7.2f | %9.2e %9.2e %7.2f | %7.2f %7.2f %7.2f%s\n", name,
                len * 1e3, e67.max_m, e67.iae_m_s, e67.time_s, arc.max_m, arc.iae_m_s, arc.time_s,
                arc.max_m / e67.max_m, arc.iae_m_s / e67.iae_m_s, arc.time_s / e67.time_s,
                better ? "" : "  (not better on all three)");
    out["held_out"].push_back(
        {{"file", h.file},
         {"layers", gp.layers},
         {"length_mm", len * 1e3},
         {"eq67",
          {{"max_cross_m", e67.max_m}, {"iae_cross_m_s", e67.iae_m_s}, {"time_s", e67.time_s}}},
         {"arc",
          {{"max_cross_m", arc.max_m}, {"iae_cross_m_s", arc.iae_m_s}, {"time_s", arc.time_s}}},
         {"constant",
          {{"ok", cs.ok},
           {"max_cross_m", cs.max_m},
           {"iae_cross_m_s", cs.iae_m_s},
           {"time_s", cs.time_s}}},
         {"every_transition",
          {{"ok", et.ok},
           {"max_cross_m", et.max_m},
           {"iae_cross_m_s", et.iae_m_s},
           {"time_s", et.time_s}}},
         {"arc_better_on_all_three", better}});
  }
  std::printf(
      "Table III's other rows on the same parts and machines:\n%-30s | %9s %9s %7s | %9s %9s "
      "%7s\n%s",
      "held-out part (layers)", "const max", "IAE", "time", "every max", "IAE", "time",
      rows_iii.c_str());
  std::printf("the arc variant better than Eq. 67 on max, IAE and time: %d of %d held-out parts\n",
              arc_better, scored);
  out["held_out_better"] = arc_better;
  out["held_out_scored"] = scored;
  return 0;
}

}  // namespace

int run_like_for_like(const StudyOptions& o, json& json_out) {
  auto layer = part_path(TestPart::fin, 1, kPaperLayerMm);
  if (!layer) {
    std::printf("%s\n", layer.error().to_string().c_str());
    return 1;
  }
  json out;
  out["paper_layer_mm"] = kPaperLayerMm;
  out["servo_period_s"] = o.servo_period_s;
  out["draws"] = o.draws;
  if (table_iii(o, *layer, out) != 0 || gap_table(o, *layer, out) != 0 || held_out(o, out) != 0 ||
      corner_table(out) != 0)
    return 1;
  json_out["like_for_like"] = std::move(out);
  return 0;
}

}  // namespace feedloop::bench_maneuver
