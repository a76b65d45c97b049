// `feedloop ident fit|excite` (see ident_command.hpp).
#include "cli/ident_command.hpp"

#include <unistd.h>  // isatty

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <sstream>
#include <string>

#include "calibration/overlay_from_ident.hpp"
#include "cli/progress.hpp"
#include "cli/text_file.hpp"
#include "config/config_source.hpp"
#include "ident/excitation.hpp"
#include "ident/fit.hpp"
#include "ident/frf.hpp"
#include "ident/report.hpp"
#include "ident/trace.hpp"
#include "sim/experiments/gantry_recording.hpp"

namespace feedloop::cli {
namespace {

void usage(std::FILE* out) {
  std::fputs(
      "usage: feedloop ident fit --trace FILE.csv --out DIR [--axis NAME] [--max-effects N] "
      "[--no-plots]\n"
      "                          [--carriage-mass-kg M]   (the carriage weighed, 0.01-100 kg; "
      "default: the\n"
      "                          thesis axis's, X 0.45, Y 1.07: a friction force is only as "
      "right as this)\n"
      "                          [--full-step-mm S]   (the drive's full step, 2 pi r / (4 n_r): "
      "the drive's own\n"
      "                          periodic error is looked for at it and at 4 S; default: none; "
      "feedloop calibrate\n"
      "                          takes it from the config's model)\n"
      "                          [--overlay CAL.yaml [--config CFG.yaml]]\n"
      "                          (--overlay: write the fitted model into a calibration overlay "
      "for\n"
      "                          feedloopd --calibration; other axes already in it are kept)\n"
      "                          [--start-mm X]   (where the trace's first command is in the "
      "machine's frame:\n"
      "                          the daemon's position_mm when the recorded job started; a "
      "recording's\n"
      "                          export counts from the job's start. The overlay's positions "
      "along the\n"
      "                          travel, the runout's phase and the belt's reference, are then "
      "the machine's)\n"
      "       feedloop ident frf --trace FILE.csv --out FRF.csv [--axis NAME] [--segment S] "
      "[--overlap F]\n"
      "                          [--window hann|rect]   (H1 and coherence, 2-125 Hz in 0.5 Hz "
      "steps)\n"
      "       feedloop ident excite --axis x|y --out FILE.csv [--effect NAME[:key=value,...]]...\n"
      "                             [--duration S (<= 3600)] [--travel MM (<= 1000)] [--seed N] "
      "[--sweep | "
      "--calibration]\n"
      "                             (--calibration: the calibration program, "
      "ident/excitation.hpp)\n"
      "effects: periodic_position:period_mm=,amplitude_um=  coulomb_friction:force_n=  "
      "backlash:width_um=\n"
      "         extra_resonance:freq_hz=,damping=,mass_kg=  time_delay:delay_ms=  "
      "scale_error:scale=\n"
      "         direction_dependent_stiffness:x0_mm= (belt anchor offset; ratio "
      "(350+x0)/(350-x0))\n",
      out);
}

bool parse_number(const std::string& s, double* v) {
  char* end = nullptr;
  *v = std::strtod(s.c_str(), &end);
  return !s.empty() && end == s.c_str() + s.size();
}

// Applies "name[:k=v,...]" to the simulator parameters; returns an error message or "".
std::string apply_effect(const std::string& spec, sim::GantryAxisParams* p) {
  const size_t colon = spec.find(':');
  const std::string name = spec.substr(0, colon);
  std::vector<std::pair<std::string, double>> kv;
  if (colon != std::string::npos) {
    std::string rest = spec.substr(colon + 1);
    size_t start = 0;
    while (start <= rest.size()) {
      const size_t comma = rest.find(',', start);
      const std::string item = rest.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
      const size_t eq = item.find('=');
      double v = 0.0;
      if (eq == std::string::npos || !parse_number(item.substr(eq + 1), &v))
        return "bad effect parameter '" + item + "' (want key=number)";
      kv.emplace_back(item.substr(0, eq), v);
      if (comma == std::string::npos) break;
      start = comma + 1;
    }
  }
  sim::GantryEffects& fx = p->effects;
  auto set = [&](const std::string& key, double* slot) -> bool {
    for (const auto& [k, v] : kv)
      if (k == key) *slot = v;
    return true;
  };
  std::vector<std::string> known;
  if (name == "periodic_position") {
    fx.periodic_position.enabled = true;
    fx.periodic_position.amplitude_um = 15.0;
    set("period_mm", &fx.periodic_position.period_mm);
    set("amplitude_um", &fx.periodic_position.amplitude_um);
    known = {"period_mm", "amplitude_um"};
  } else if (name == "coulomb_friction") {
    fx.coulomb_friction = {true, 2.0};
    set("force_n", &fx.coulomb_friction.force_n);
    known = {"force_n"};
  } else if (name == "backlash") {
    fx.backlash = {true, 30.0};
    set("width_um", &fx.backlash.width_um);
    known = {"width_um"};
  } else if (name == "extra_resonance") {
    fx.extra_resonance.enabled = true;
    fx.extra_resonance.freq_hz = 40.0;
    set("freq_hz", &fx.extra_resonance.freq_hz);
    set("damping", &fx.extra_resonance.damping);
    set("mass_kg", &fx.extra_resonance.mass_kg);
    known = {"freq_hz", "damping", "mass_kg"};
  } else if (name == "time_delay") {
    fx.time_delay = {true, 3.0};
    set("delay_ms", &fx.time_delay.delay_ms);
    known = {"delay_ms"};
  } else if (name == "scale_error") {
    fx.scale_error = {true, 1.003};
    set("scale", &fx.scale_error.scale);
    known = {"scale"};
  } else if (name == "direction_dependent_stiffness") {
    p->belt_span_mm = 350.0;
    p->belt_x0_mm = 100.0;
    set("x0_mm", &p->belt_x0_mm);
    known = {"x0_mm"};
  } else {
    return "unknown effect '" + name + "'";
  }
  for (const auto& [k, v] : kv) {
    bool ok = false;
    for (const auto& n : known) ok = ok || n == k;
    if (!ok) return "effect '" + name + "' has no parameter '" + k + "'";
  }
  return "";
}

int excite(const std::vector<std::string>& args) {
  std::string axis = "x", out;
  ident::RandomMovesOptions ro;
  bool sweep = false, calibration = false;
  bool direction = false;
  std::vector<std::string> effects;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    const bool has_value = i + 1 < args.size();
    double v = 0.0;
    if (a == "--axis" && has_value) {
      axis = args[++i];
    } else if (a == "--out" && has_value) {
      out = args[++i];
    } else if (a == "--effect" && has_value) {
      effects.push_back(args[++i]);
      direction = direction || effects.back().rfind("direction_dependent_stiffness", 0) == 0;
    } else if (a == "--duration" && has_value && parse_number(args[i + 1], &v) && v > 0.0 &&
               v <= 3600.0) {
      ro.duration_s = v;
      ++i;
    } else if (a == "--travel" && has_value && parse_number(args[i + 1], &v) && v >= 0.0 &&
               v <= 1000.0) {
      ro.travel_mm = v;
      ++i;
    } else if (a == "--seed" && has_value && parse_number(args[i + 1], &v)) {
      ro.seed = static_cast<uint64_t>(v);
      ++i;
    } else if (a == "--sweep") {
      sweep = true;
    } else if (a == "--calibration") {
      calibration = true;
    } else if (a == "--help" || a == "-h") {
      usage(stdout);
      return 0;
    } else {
      std::fprintf(stderr, "feedloop ident excite: bad argument '%s'\n", a.c_str());
      usage(stderr);
      return 2;
    }
  }
  if (out.empty() || (axis != "x" && axis != "y") || (sweep && calibration)) {
    usage(stderr);
    return 2;
  }
  sim::GantryAxisParams p = axis == "x" ? sim::thesis_x_axis() : sim::thesis_y_axis();
  p.belt_span_mm = 1e6;  // a belt the linear model explains everywhere, unless asked otherwise
  for (const auto& e : effects) {
    const std::string err = apply_effect(e, &p);
    if (!err.empty()) {
      std::fprintf(stderr, "feedloop ident excite: %s\n", err.c_str());
      return 2;
    }
  }
  if (direction) ro.travel_mm = 0.0;  // a constant stiffness ratio needs a fixed position
  std::vector<double> cmd;
  if (sweep) {
    ident::SineSweepOptions so;
    so.duration_s = ro.duration_s;
    cmd = ident::sine_sweep(so);
  } else if (calibration) {
    ident::CalibrationProgramOptions co;
    co.seed = ro.seed;
    co.travel_mm = ro.travel_mm;
    if (direction) co.run_mm = 0.0;
    cmd = ident::calibration_program(co);
  } else {
    cmd = ident::random_moves(ro);
  }
  auto trace = sim::record_gantry_trace(p, cmd, ro.sample_rate_hz, axis);
  if (!trace) {
    std::fprintf(stderr, "feedloop ident excite: %s\n", trace.error().to_string().c_str());
    return 1;
  }
  if (auto s = ident::write_trace_csv(out, trace.value()); !s) {
    std::fprintf(stderr, "feedloop ident excite: %s\n", s.error().to_string().c_str());
    return 1;
  }
  std::printf("wrote %s: %zu samples, axis %s\n", out.c_str(), trace.value().samples(), axis.c_str());
  return 0;
}

// The fitted axis into the overlay at `path` (kept: the other axes already in it), written to a
// temporary file and renamed over it, so a reader never sees half of it.
Status write_overlay(const std::string& path, const config::MachineConfig& base,
                     const ident::IdentResult& r, const std::string& source) {
  auto existing = read_existing_text_file(path);
  if (!existing) return existing.error();
  auto yaml = calibration::merge_overlay(base, existing.value().value_or(""), path,
                                         calibration::with_carried_model(r), source);
  if (!yaml) return yaml.error();
  return write_text_file(path, yaml.value());
}

int fit(const std::vector<std::string>& args) {
  std::string trace_path, out_dir, axis_name, overlay_path, config_path;
  ident::ReportOptions report_options;
  ident::FitOptions o;
  double start_mm = std::numeric_limits<double>::quiet_NaN();  // --start-mm: NaN, the trace's frame
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    const bool has_value = i + 1 < args.size();
    double v = 0.0;
    if (a == "--trace" && has_value) {
      trace_path = args[++i];
    } else if (a == "--max-effects" && has_value && parse_number(args[i + 1], &v) && v >= 0.0 && v <= 7.0 &&
               v == static_cast<int>(v)) {
      o.max_effects = static_cast<int>(v);
      ++i;
    } else if (a == "--carriage-mass-kg" && has_value && parse_number(args[i + 1], &v) &&
               v >= 0.01 && v <= 100.0) {
      o.carriage_mass_kg = v;
      ++i;
    } else if (a == "--full-step-mm" && has_value && parse_number(args[i + 1], &v) && v >= 0.001 &&
               v <= 10.0) {
      o.full_step_mm = v;
      ++i;
    } else if (a == "--out" && has_value) {
      out_dir = args[++i];
    } else if (a == "--axis" && has_value) {
      axis_name = args[++i];
    } else if (a == "--start-mm" && has_value && parse_number(args[i + 1], &v) &&
               std::abs(v) <= 1e4) {
      start_mm = v;
      ++i;
    } else if (a == "--overlay" && has_value) {
      overlay_path = args[++i];
    } else if (a == "--config" && has_value) {
      config_path = args[++i];
    } else if (a == "--no-plots") {
      report_options.plots = false;
    } else if (a == "--help" || a == "-h") {
      usage(stdout);
      return 0;
    } else {
      std::fprintf(stderr, "feedloop ident fit: bad argument '%s'\n", a.c_str());
      usage(stderr);
      return 2;
    }
  }
  if (trace_path.empty() || out_dir.empty()) {
    usage(stderr);
    return 2;
  }
  // Where the overlay goes, and the config it is read against, are checked before the fit, not
  // after it.
  std::optional<config::MachineConfig> overlay_base;
  if (!overlay_path.empty()) {
    const auto parent = std::filesystem::path(overlay_path).parent_path();
    if (!parent.empty() && !std::filesystem::is_directory(parent)) {
      std::fprintf(stderr, "feedloop ident fit: --overlay %s: no directory %s\n",
                   overlay_path.c_str(), parent.string().c_str());
      return 1;
    }
    auto base = config::load_machine_config({config_path, "", false});
    if (!base) {
      std::fprintf(stderr, "feedloop ident fit: %s\n", base.error().to_string().c_str());
      return 1;
    }
    overlay_base = std::move(base.value().config);
    if (auto existing = read_existing_text_file(overlay_path); !existing) {
      std::fprintf(stderr, "feedloop ident fit: --overlay %s\n",
                   existing.error().to_string().c_str());
      return 1;
    }
  }
  const auto t0 = std::chrono::steady_clock::now();
  auto read = ident::read_trace_csv(trace_path);
  std::string resampled;
  auto trace = read ? ident::evenly_sampled(read.value(), trace_path, &resampled) : read;
  if (!trace) {
    std::fprintf(stderr, "feedloop ident fit: %s\n", trace.error().to_string().c_str());
    return 1;
  }
  if (!resampled.empty())
    std::fprintf(stderr, "feedloop ident fit: %s: %s\n", trace_path.c_str(), resampled.c_str());
  const ident::Trace& tr = trace.value();
  const ident::AxisTrace* axis = axis_name.empty() ? &tr.axes.front() : tr.axis(axis_name);
  if (axis == nullptr) {
    std::fprintf(stderr, "feedloop ident fit: %s: no axis '%s' in the trace\n", trace_path.c_str(), axis_name.c_str());
    return 1;
  }
  // The trace moved into the machine's frame (--start-mm), as `feedloop calibrate` moves its
  // recordings: command and measurement by the same offset, so the fit is the same and only the
  // positions along the travel that the overlay carries change.
  std::vector<double> cmd_mm = axis->cmd_mm, meas_mm = axis->meas_mm;
  if (std::isfinite(start_mm) && !cmd_mm.empty()) {
    const double to_machine_mm = start_mm - cmd_mm.front();
    for (double& u : cmd_mm) u += to_machine_mm;
    for (double& y : meas_mm) y += to_machine_mm;
  }
  Progress progress("ident fit " + axis->name);
  // The progress bar only on a terminal: logs and pipes get the result lines alone.
  const bool tty = ::isatty(2) != 0;
  if (tty) o.progress = [&](double f, const std::string& what) { progress.update(f, what); };
  auto r = ident::identify_axis(axis->name, cmd_mm, meas_mm, tr.period_s(), o);
  if (tty) progress.finish();
  if (!r) {
    std::fprintf(stderr, "feedloop ident fit: %s: axis %s: %s\n", trace_path.c_str(),
                 axis->name.c_str(), r.error().to_string().c_str());
    return 1;
  }
  ident::ReportExtras extras;
  if (auto s = ident::write_report(out_dir, r.value(), tr.time_s, cmd_mm, meas_mm, tr.period_s(),
                                   trace_path, report_options, &extras);
      !s) {
    std::fprintf(stderr, "feedloop ident fit: %s\n", s.error().to_string().c_str());
    return 1;
  }
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const auto& res = r.value();
  for (const std::string& w : res.warnings)
    std::fprintf(stderr, "feedloop ident fit: %s: axis %s: warning: %s\n", trace_path.c_str(),
                 res.axis.c_str(), w.c_str());
  std::printf("axis %s: baseline %.3f um RMS -> augmented %.3f um RMS; effects:", res.axis.c_str(),
              res.baseline_rms_um, res.augmented_rms_um);
  if (res.effects.empty()) std::printf(" none");
  for (auto e : res.effects) {
    std::printf(" %s(", ident::effect_name(e));
    bool first = true;
    for (const auto& [k, v] : ident::effect_params_report(res.augmented, e)) {
      std::printf("%s%s=%.5g", first ? "" : ", ", k.c_str(), v);
      first = false;
    }
    std::printf(")");
  }
  std::printf("\nwrote %s/report.json, report.md, residual.csv, frf.csv and %zu plots (%.1f s)\n", out_dir.c_str(),
              extras.plots.size(), secs);
  if (!extras.plot_note.empty()) std::printf("note: %s\n", extras.plot_note.c_str());
  if (!overlay_path.empty()) {
    if (auto w =
            write_overlay(overlay_path, *overlay_base, res, "feedloop ident fit of " + trace_path);
        !w) {
      std::fprintf(stderr, "feedloop ident fit: %s\n", w.error().to_string().c_str());
      return 1;
    }
    std::printf("wrote the calibration overlay %s (axis %s)\n", overlay_path.c_str(),
                res.axis.c_str());
    const bool placed = res.carried.has(ident::Effect::kPeriodicPosition) ||
                        res.carried.compliance_slope_per_m != 0.0;
    if (placed && !std::isfinite(start_mm))
      std::fprintf(
          stderr,
          "feedloop ident fit: note: the overlay places the %s along the travel in the "
          "trace's frame (its first command at %.4g mm); if the recorded job did not "
          "start at that machine position, fit again with --start-mm (the daemon's "
          "position_mm when the job started)\n",
          res.carried.has(ident::Effect::kPeriodicPosition) ? "runout's phase" : "belt's stiffness",
          axis->cmd_mm.front());
  }
  return 0;
}

int frf(const std::vector<std::string>& args) {
  std::string trace_path, out_path, axis_name;
  ident::WelchOptions wo;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    const bool has_value = i + 1 < args.size();
    double v = 0.0;
    if (a == "--trace" && has_value) {
      trace_path = args[++i];
    } else if (a == "--out" && has_value) {
      out_path = args[++i];
    } else if (a == "--axis" && has_value) {
      axis_name = args[++i];
    } else if (a == "--segment" && has_value && parse_number(args[i + 1], &v) && v > 0.0) {
      wo.segment_s = v;
      ++i;
    } else if (a == "--overlap" && has_value && parse_number(args[i + 1], &v)) {
      wo.overlap = v;
      ++i;
    } else if (a == "--window" && has_value && (args[i + 1] == "hann" || args[i + 1] == "rect")) {
      wo.window = args[++i] == "hann" ? ident::FrfWindow::kHann : ident::FrfWindow::kRectangular;
    } else if (a == "--help" || a == "-h") {
      usage(stdout);
      return 0;
    } else {
      std::fprintf(stderr, "feedloop ident frf: bad argument '%s'\n", a.c_str());
      usage(stderr);
      return 2;
    }
  }
  if (trace_path.empty() || out_path.empty()) {
    usage(stderr);
    return 2;
  }
  auto read = ident::read_trace_csv(trace_path);
  std::string resampled;
  auto trace = read ? ident::evenly_sampled(read.value(), trace_path, &resampled) : read;
  if (!trace) {
    std::fprintf(stderr, "feedloop ident frf: %s\n", trace.error().to_string().c_str());
    return 1;
  }
  if (!resampled.empty())
    std::fprintf(stderr, "feedloop ident frf: %s: %s\n", trace_path.c_str(), resampled.c_str());
  const ident::Trace& tr = trace.value();
  const ident::AxisTrace* axis = axis_name.empty() ? &tr.axes.front() : tr.axis(axis_name);
  if (axis == nullptr) {
    std::fprintf(stderr, "feedloop ident frf: %s: no axis '%s' in the trace\n", trace_path.c_str(), axis_name.c_str());
    return 1;
  }
  const double period_s = tr.period_s();
  auto est = ident::estimate_frf_h1(axis->cmd_mm, axis->meas_mm, period_s > 0.0 ? 1.0 / period_s : 0.0, {}, wo);
  if (!est) {
    std::fprintf(stderr, "feedloop ident frf: %s: %s\n", trace_path.c_str(), est.error().to_string().c_str());
    return 1;
  }
  if (auto s = ident::write_frf_csv(out_path, est.value()); !s) {
    std::fprintf(stderr, "feedloop ident frf: %s\n", s.error().to_string().c_str());
    return 1;
  }
  int coherent = 0;
  for (double c : est.value().coherence) coherent += c > 0.9 ? 1 : 0;
  std::printf("wrote %s: axis %s, %zu points 2-125 Hz, %d segments of %.3g s, coherence > 0.9 at %d points\n",
              out_path.c_str(), axis->name.c_str(), est.value().freq_hz.size(), est.value().segments,
              est.value().segment_s, coherent);
  return 0;
}

}  // namespace

int ident_command(const std::vector<std::string>& args) {
  if (args.empty()) {
    usage(stderr);
    return 2;
  }
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  if (args[0] == "fit") return fit(rest);
  if (args[0] == "excite") return excite(rest);
  if (args[0] == "frf") return frf(rest);
  if (args[0] == "--help" || args[0] == "-h" || args[0] == "help") {
    usage(stdout);
    return 0;
  }
  std::fprintf(stderr, "feedloop ident: unknown subcommand '%s'\n", args[0].c_str());
  usage(stderr);
  return 2;
}

}  // namespace feedloop::cli
