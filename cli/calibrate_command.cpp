// `feedloop calibrate` (calibrate_command.hpp).
#include "cli/calibrate_command.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <optional>
#include <sstream>
#include <thread>
#include <utility>
#include <vector>

#include "calibration/excitation_gcode.hpp"
#include "calibration/overlay_from_ident.hpp"
#include "cli/line_connection.hpp"
#include "cli/text_file.hpp"
#include "config/calibration.hpp"
#include "config/config.hpp"
#include "config/config_source.hpp"
#include "ident/fit.hpp"
#include "ident/report.hpp"
#include "recorder/replay.hpp"
#include "recorder/trace_export.hpp"

namespace feedloop::cli {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

// By default a calibrated model whose check pattern tracks more than 10 % worse than the model it
// replaces is not kept (--max-worse-pct; the check's e_t repeats to well within that in virtual
// time; the first simulator's exact model against its own fit: +4 %).
constexpr double kDefaultMaxWorsePct = 10.0;

void usage(std::FILE* out) {
  std::fputs(
      "usage: feedloop calibrate [--axes x,y] [--out DIR] [--api PATH] [--no-install] [--seed N]\n"
      "                          [--max-worse-pct P] [--keep-pi-gains]\n"
      "       feedloop calibrate --check-only [--api PATH]   (the check pattern's e_t alone)\n"
      "       feedloop calibrate --write-gcode DIR [--config CFG.yaml] [--axes x,y] [--seed N]\n"
      "  Runs the calibration program on each axis of the machine a running feedloopd drives (as\n"
      "  print jobs), identifies each axis from the recordings, writes the calibration overlay "
      "and\n"
      "  a before/after report (e_t of a check pattern, residual RMS, named effects, plots) into\n"
      "  DIR (default: calibration), installs the overlay where the daemon reads it and reloads.\n"
      "  A calibrated model that cannot print the check pattern, or tracks it over 10 % worse "
      "than\n"
      "  the model it replaces, is not kept (exit 1; the previous calibration is back).\n"
      "  With control.mode pi it then scales the PI gains of the calibrated axes by 1/2 and 1/4\n"
      "  while each tracks the check pattern better, and installs the best (the overlay's\n"
      "  control.axes; the loop stays closed); --keep-pi-gains keeps the config's gains.\n"
      "  --no-install: write it only. --write-gcode: only write the programs (no daemon).\n"
      "  Default API socket: ${RUNTIME_DIR}/api.sock. docs/calibration.md.\n",
      out);
}

// JSON-RPC 2.0 calls on the daemon's API socket, one at a time.
class Api {
 public:
  bool open(const std::string& path) {
    path_ = path;
    return c_.open(path);
  }
  void reopen() {
    c_.close();
    (void)c_.open(path_);
  }
  Result<json> call(const std::string& method, const json& params = json::object(), int timeout_ms = 30000) {
    const int id = ++id_;
    if (!c_.send(json{{"jsonrpc", "2.0"}, {"id", id}, {"method", method}, {"params", params}}.dump() + "\n"))
      return Error{"the daemon closed the API socket (" + method + ")"};
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
    while (std::chrono::steady_clock::now() < deadline) {
      auto line = c_.read_line(1000);
      if (!line) continue;
      json r = json::parse(*line, nullptr, false);
      if (!r.is_object() || r.value("id", -1) != id) continue;  // a notification
      if (r.contains("error")) return Error{method + ": " + r["error"].value("message", std::string("error"))};
      return r["result"];
    }
    return Error{method + ": no answer within " + std::to_string(timeout_ms / 1000) + " s"};
  }

 private:
  Connection c_;
  std::string path_;
  int id_ = 0;
};

// The machine's tracking error counters (cumulative since the machine was built).
struct EtCounter {
  double mean_mm = 0.0;
  double samples = 0.0;
};
EtCounter et_counter(const json& status) {
  const json& t = status["motion"]["tracking_error_mm"];
  return {t.value("mean", 0.0), static_cast<double>(t.value("samples", 0ULL))};
}
// Mean e_t over the samples between two readings of the counters.
double et_between(const EtCounter& a, const EtCounter& b) {
  const double n = b.samples - a.samples;
  return n > 0.0 ? (b.mean_mm * b.samples - a.mean_mm * a.samples) / n : NAN;
}

// The check pattern: thesis Sect. 5.2's circle (r 20 mm, 50 chords) and small star (r 5 / 2 mm),
// at 90 mm/s around (cx, cy), each from rest after a 300 ms dwell.
std::string check_pattern(double cx, double cy) {
  std::ostringstream g;
  char buf[96];
  // From rest at (cx + 20, cy), where check_start() brought the machine: every run of it then
  // covers the same motion, wherever the machine was before.
  g << "; feedloop calibrate: check pattern\nG90\nG4 P300\n";
  for (int i = 1; i <= 50; ++i) {
    const double a = 2.0 * M_PI * i / 50.0;
    std::snprintf(buf, sizeof buf, "G1 X%.4f Y%.4f F5400\n", cx + 20.0 * std::cos(a), cy + 20.0 * std::sin(a));
    g << buf;
  }
  for (int i = 0; i <= 10; ++i) {
    const double r = i % 2 == 0 ? 5.0 : 2.0, a = M_PI / 2.0 + M_PI * i / 5.0;
    std::snprintf(buf, sizeof buf, "G1 X%.4f Y%.4f F%d\n%s", cx + r * std::cos(a), cy + r * std::sin(a),
                  i == 0 ? 3000 : 5400, i == 0 ? "G4 P300\n" : "");
    g << buf;
  }
  g << "M400\n";
  return g.str();
}

// The travel to the check pattern's start, its last leg always the same (the belts' stretch and
// the loops' state at the start then do not depend on where the machine came from).
std::string check_start(double cx, double cy) {
  char buf[128];
  std::snprintf(buf, sizeof buf, "G90\nG1 X%.4f Y%.4f F3000\nG1 X%.4f Y%.4f F3000\nG4 P500\nM400\n",
                cx, cy - 30.0, cx + 20.0, cy);
  return buf;
}

struct Plan {
  std::vector<std::string> axes{"x", "y"};
  double cx = 0.0, cy = 0.0;
  std::vector<std::string> programs;  // per axis
  std::vector<std::string> gentle_programs;  // per axis, at kGentle of the acceleration and speed
  std::string check_start, check;
};

// The second excitation of an axis whose first recording no model describes (a carriage that lost
// steps): the program again at this share of the acceleration and of the speed.
constexpr double kGentle = 0.5;

Result<Plan> make_plan(const config::MachineConfig& cfg, const std::vector<std::string>& axes, uint64_t seed) {
  if (cfg.kinematics == config::Kinematics::delta)
    return Error{
        "a delta is calibrated from FRFs (feedloop ident delta; docs/ident_delta.md), not here"};
  Plan p;
  p.axes = axes;
  const config::AxisConfig* ax[2] = {cfg.axis("x"), cfg.axis("y")};
  for (const config::AxisConfig* a : ax)
    if (a == nullptr || !std::isfinite(a->min_mm) || !std::isfinite(a->max_mm))
      return Error{"the config's x and y axes need min_mm and max_mm"};
  p.cx = 0.5 * (ax[0]->min_mm + ax[0]->max_mm);
  p.cy = 0.5 * (ax[1]->min_mm + ax[1]->max_mm);
  p.check_start = check_start(p.cx, p.cy);
  p.check = check_pattern(p.cx, p.cy);
  if (axes.empty()) return Error{"--axes names no axis (it takes x, y or x,y)"};
  for (const std::string& name : axes) {
    const config::AxisConfig* a = name == "x" ? ax[0] : name == "y" ? ax[1] : nullptr;
    if (a == nullptr) return Error{"--axes takes x and y (not '" + name + "')"};
    if (std::count(axes.begin(), axes.end(), name) > 1)
      return Error{"--axes names " + name + " twice"};
    calibration::ExcitationGcodeOptions o;
    o.axis = name == "x" ? 'X' : 'Y';
    o.travel_mm = std::min(80.0, 0.6 * (a->max_mm - a->min_mm));
    o.start_mm = 0.5 * (a->min_mm + a->max_mm) - 0.5 * o.travel_mm;
    o.accel_mm_s2 = std::min(a->max_accel_mm_s2, 6000.0);
    o.max_speed_mm_s = std::min(a->max_velocity_mm_s, 150.0);
    o.seed = seed;
    const double other = name == "x" ? p.cy : p.cx;
    char head[64];
    std::snprintf(head, sizeof head, "G90\nG1 %c%.4f F3000\n", name == "x" ? 'Y' : 'X', other);
    p.programs.push_back(head + calibration::excitation_gcode(o));
    o.accel_mm_s2 *= kGentle;
    o.max_speed_mm_s *= kGentle;
    p.gentle_programs.push_back(head + calibration::excitation_gcode(o));
  }
  return p;
}

// Runs `gcode` as the print job `name` and waits for it to end; returns the recording's last part.
Result<std::string> run_job(Api& api, const std::string& name, const std::string& gcode, const std::string& what) {
  auto st = api.call("status");
  if (!st) return st.error();
  const std::string before = st.value()["recorder"].value("last_print", "");
  if (auto u = api.call("files.upload", {{"filename", name}, {"content", gcode}}); !u) return u.error();
  if (auto s = api.call("job.start", {{"filename", name}}); !s) return s.error();
  std::fprintf(stderr, "calibrate: %s ...", what.c_str());
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0;; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    auto j = api.call("job.status");
    if (!j) return j.error();
    const std::string state = j.value().value("state", "");
    if (i % 20 == 0) std::fprintf(stderr, ".");
    if (state == "complete") break;
    if (state == "cancelled" || state == "error" || state == "off")
      return Error{"the job " + name + " ended " + state + ": " + j.value().value("message", "")};
    if (std::chrono::steady_clock::now() - t0 > std::chrono::minutes(30))
      return Error{"the job " + name + " did not end within 30 min"};
  }
  // The recording closes when the machine is idle and nobody owns it.
  for (int i = 0; i < 600; ++i) {
    auto s = api.call("status");
    if (!s) return s.error();
    const json& rec = s.value()["recorder"];
    if (!rec.value("recording", false) && rec.value("last_print", "") != before && !rec.value("last_print", "").empty()) {
      std::fprintf(stderr, " %.1f s\n", std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      if (!s.value().value("last_error", "").empty())
        return Error{"the machine reported a fault: " + s.value()["last_error"].get<std::string>()};
      return rec["last_print"].get<std::string>();
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return Error{"the daemon did not close the recording of " + name +
               " (is the recorder on? recorder.enabled in the config)"};
}

// Homes X and Y when the machine has not (a job of its own, so the programs' recordings hold
// only their own moves).
Status home_if_needed(Api& api) {
  auto st = api.call("status");
  if (!st) return st.error();
  const std::string homed = st.value().value("homed_axes", "");
  if (homed.find('x') != std::string::npos && homed.find('y') != std::string::npos) return Status{};
  auto r = run_job(api, "feedloop_calibrate_home.gcode", "G28\n", "homing");
  if (!r) return r.error();
  return Status{};
}

// e_t of the check pattern: the counters read around its job.
Result<double> check_et(Api& api, const Plan& plan, const std::string& what) {
  if (Status h = home_if_needed(api); !h) return h.error();
  if (auto t = run_job(api, "feedloop_calibrate_check_start.gcode", plan.check_start,
                       "to the check pattern");
      !t)
    return t.error();
  auto a = api.call("status");
  if (!a) return a.error();
  auto r = run_job(api, "feedloop_calibrate_check.gcode", plan.check, what);
  if (!r) return r.error();
  auto b = api.call("status");
  if (!b) return b.error();
  return et_between(et_counter(a.value()), et_counter(b.value()));
}

// Asks the daemon to rebuild its machine from its config (and calibration), open loop or as
// configured, and waits until it has.
Status reload(Api& api, bool open_loop, bool no_feedforward = false) {
  auto st0 = api.call("status");
  if (!st0) return st0.error();
  const auto reloads = st0.value().value("config_reloads", 0ULL);
  if (auto r =
          api.call("config.reload", {{"open_loop", open_loop}, {"no_feedforward", no_feedforward}});
      !r)
    return r.error();
  for (int i = 0; i < 300; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    auto st = api.call("status");
    if (!st) {
      api.reopen();  // a reload may drop the machine's clients
      continue;
    }
    if (st.value().value("config_reloads", 0ULL) > reloads) return Status{};
  }
  return Error{"the daemon did not reload its config within 30 s"};
}

// The effects of calibration::effects_tried_on_the_machine (an extra mode, a periodic position
// error) on the check pattern:
// the overlay with each axis of `to_try` carrying its identified model with them (fitted with
// nothing left out) is installed and tracked; it is kept when it tracks better than `e_t_without`
// (the overlay installed, the carried models without them), and the daemon goes back to `overlay`
// otherwise. A mode identification names may be of another structure than the model's mass on
// the carriage (the second simulator's distributed belt), and the feedforward's inverse of it
// then tracks worse (docs/calibration.md, "The extra mode carried"); a periodic error named
// beside a backlash (the second simulator's backlash draw 1, Y: 8.9 um at 2.08 mm, which no part
// of that machine has) put a ripple into the steps that the carriage then printed. A fault on the
// check pattern counts as worse. Returns the overlay installed; report["mode_trial"] says what was
// tried.
Result<std::string> try_effects_on_the_machine(
    Api& api, const Plan& plan, const config::MachineConfig& cfg,
    const std::vector<std::pair<ident::IdentResult, std::string>>& to_try,
    const std::string& overlay, const std::string& overlay_path, const std::string& target,
    double e_t_without, json& report) {
  std::string with = overlay;
  json axes = json::array();
  json effects = json::array();  // [axis, name] of every effect tried
  for (const auto& [r, recording] : to_try) {
    for (ident::Effect e : calibration::effects_tried_on_the_machine())
      if (r.augmented.has(e)) effects.push_back({r.axis, ident::effect_name(e)});
    auto merged =
        calibration::merge_overlay(cfg, with, overlay_path, calibration::with_carried_model(r),
                                   "feedloop calibrate, recording " + recording);
    if (!merged) return merged.error();
    with = merged.value();
    axes.push_back(r.axis);
  }
  auto install = [&](const std::string& text) -> Status {
    if (Status s = write_text_file(target, text); !s) return s;
    return reload(api, false);
  };
  // A fitted mode outside the config's ranges (a mass of hundreds of kilograms) is no model to
  // try: the daemon would refuse to reload it. Not tried; the model without it stays.
  if (auto valid = config::apply_calibration_text(cfg, with, overlay_path); !valid) {
    report["mode_trial"] = {{"axes", axes},
                            {"effects", effects},
                            {"e_t_without_mm", e_t_without},
                            {"e_t_with_mm", nullptr},
                            {"error", valid.error().to_string()},
                            {"kept", false}};
    std::printf("with the named effects %s: not tried: %s\n", effects.dump().c_str(),
                valid.error().to_string().c_str());
    return overlay;
  }
  if (Status s = install(with); !s) return s.error();
  auto e = check_et(api, plan, "check pattern (with the named effects)");
  json trial = {{"axes", axes}, {"effects", effects}, {"e_t_without_mm", e_t_without}};
  if (e) {
    trial["e_t_with_mm"] = e.value();
    std::printf("with the named effects %s: e_t %.4f mm against %.4f without\n",
                effects.dump().c_str(), e.value(), e_t_without);
  } else {
    trial["e_t_with_mm"] = nullptr;
    trial["error"] = e.error().message;
    std::printf("with the named effects: %s\n", e.error().message.c_str());
  }
  const bool keep = e && std::isfinite(e.value()) && e.value() < e_t_without;
  trial["kept"] = keep;
  report["mode_trial"] = trial;
  if (keep) {
    report["e_t_mm"]["after"] = e.value();
    return with;
  }
  if (Status s = install(overlay); !s) return s.error();
  return overlay;
}

// The other start's fit is tried on the machine when its carried model predicts the held-out part
// within this factor of the chosen one's and is another model (a spring 25 % apart or other
// effects). On the second simulator's friction draw 1 (X: 3.0 N of LuGre friction on a carriage of
// 1.04 kg) the Y start predicted calibrate's recording better (12.0 um held out against 21.3) with
// the springs' roles swapped (k1 25.6 kN/m, k2 2 MN/m), and its inverse tracked the thesis's
// large star 2.7 times worse than the X start's (k1 rigid, k2 21.1 kN/m: a belt of the machine's
// 23.9 kN/m): held-out RMS over a recording is not the tracking of a print.
constexpr double kOtherStartFactor = 2.0;
// ... and it is kept when it tracks the check pattern this much better (relative): the first
// simulator with an 8 ms encoder delay rings at the config's PI gains (0.39 mm), where the two
// starts' models tracked 0.8 % apart, and the other one (its delay 11 % off the drawn one, the
// first's 2 %) was kept on that difference alone.
constexpr double kOtherStartMinGain = 0.05;

// The other start's model of each axis (AxisOutcome::other_start) on the check pattern: the
// overlay with that axis's model replaced is installed and tracked, and kept when it tracks
// better than `e_t_chosen` (the overlay as it is) by kOtherStartMinGain; the daemon goes back to
// `overlay` otherwise.
// A fault on the check pattern counts as worse. Axes one at a time, each against the best so
// far. report["start_trial"] says what was tried; a kept model's figures replace the axis's in
// report["axes"] and its identification report replaces the axis's.
struct OtherStart {
  ident::IdentResult fit;
  std::string recording;
  std::function<Status(const ident::IdentResult&)> write_axis_report;
};
Result<std::string> try_other_starts_on_the_machine(
    Api& api, const Plan& plan, const config::MachineConfig& cfg,
    const std::vector<OtherStart>& others, std::string overlay, const std::string& overlay_path,
    const std::string& target, double e_t_chosen, json& report) {
  for (const OtherStart& o : others) {
    const std::string& axis = o.fit.axis;
    json trial = {{"axis", axis},
                  {"e_t_chosen_mm", e_t_chosen},
                  {"held_out_other_um", o.fit.carried_validation_rms_um}};
    auto merged = calibration::merge_overlay(cfg, overlay, overlay_path,
                                             calibration::with_carried_model(o.fit),
                                             "feedloop calibrate, recording " + o.recording);
    if (!merged) return merged.error();
    // A model outside the config's ranges is no model to try: the daemon would refuse it.
    if (auto valid = config::apply_calibration_text(cfg, merged.value(), overlay_path); !valid) {
      trial["e_t_other_mm"] = nullptr;
      trial["error"] = valid.error().to_string();
      trial["kept"] = false;
      report["start_trial"].push_back(trial);
      continue;
    }
    if (Status s = write_text_file(target, merged.value()); !s) return s.error();
    if (Status s = reload(api, false); !s) return s.error();
    auto e = check_et(api, plan, "check pattern (axis " + axis + ", the other start's model)");
    const bool keep =
        e && std::isfinite(e.value()) && e.value() < (1.0 - kOtherStartMinGain) * e_t_chosen;
    trial["e_t_other_mm"] = e ? json(e.value()) : json(nullptr);
    if (!e) trial["error"] = e.error().message;
    trial["kept"] = keep;
    std::printf("axis %s, the other start's model: e_t %.4f mm against %.4f: %s\n", axis.c_str(),
                e ? e.value() : NAN, e_t_chosen, keep ? "kept" : "not kept");
    report["start_trial"].push_back(trial);
    if (!keep) continue;
    overlay = merged.value();
    e_t_chosen = e.value();
    report["e_t_mm"]["after"] = e_t_chosen;
    for (json& a : report["axes"])
      if (a["axis"] == axis) {
        a["baseline_rms_um"] = o.fit.baseline_rms_um;
        a["augmented_rms_um"] = o.fit.augmented_rms_um;
        a["held_out_before_um"] = o.fit.baseline_validation_rms_um;
        a["held_out_after_um"] = o.fit.augmented_validation_rms_um;
        a["warnings"] = o.fit.warnings;
        a["other_start"] = true;
      }
    if (o.write_axis_report) {
      if (Status s = o.write_axis_report(o.fit); !s) return s.error();
    }
  }
  // The overlay kept is the one installed.
  if (Status s = write_text_file(target, overlay); !s) return s.error();
  if (Status s = reload(api, false); !s) return s.error();
  return overlay;
}

// The switching effects' sizes the model carries, tried on the check pattern: the friction force
// and the dead band. Identification's friction is a Dahl bristle and its dead band sharp; a
// machine's may follow other laws (the second simulator's LuGre friction breaks away at 1.1-1.4
// times its sliding force and slides in its bristles first), and the inverse of the identified
// size then pushes the motor at the wrong force, or crosses the wrong gap, at every reversal: on
// that simulator's friction draw 1 the check pattern tracked 0.0304 mm with the carried forces and
// 0.0277 with X's halved, while Y's force helped (docs/calibration.md, "The sizes tried on the
// machine"). Each size an axis's model carries (a friction of at least kSizeTrialMinFrictionN, any
// dead band) is tracked at x 1/2 (then 0 while that tracks better), or x 3/2 when the half does
// not, with the config's PI gains; a scale is kept when it tracks kSizeTrialMinGain better than the
// best so far. Axes and sizes one at a time, each against the best so far. report["size_trial"]
// says what was tried; a fault on the check pattern counts as worse.
constexpr double kSizeTrialMinFrictionN = 0.5;  // ident::FitOptions::min_friction_n: a named one
// 5 %, as for the other start's model: on the backlash draw 2 a dead band x 3/2 tracked 3 % better
// with the config's gains (0.0131 against 0.0135 mm) and, once the gains were chosen, 9 % worse
// than the identified one (0.0122 against 0.0112).
constexpr double kSizeTrialMinGain = kOtherStartMinGain;
struct CarriedSize {
  const char* name;  // the overlay's key
  double config::GantryModelConfig::*size;
  double min;  // tried from this size
};
constexpr CarriedSize kCarriedSizes[] = {
    {"coulomb_friction_n", &config::GantryModelConfig::coulomb_friction_n, kSizeTrialMinFrictionN},
    {"backlash_mm", &config::GantryModelConfig::backlash_mm, 1e-9},
};
Result<std::string> try_sizes_on_the_machine(Api& api, const Plan& plan,
                                             const config::MachineConfig& cfg,
                                             const std::vector<std::string>& axes,
                                             std::string overlay, const std::string& overlay_path,
                                             const std::string& target, double e_t_best,
                                             json& report) {
  auto applied = config::apply_calibration_text(cfg, overlay, overlay_path);
  if (!applied) return applied.error();
  bool tried_any = false;
  for (const std::string& axis : axes)
    for (const CarriedSize& c : kCarriedSizes) {
      const config::GantryModelConfig* g = applied.value().config.model.gantry_for(axis);
      if (g == nullptr || !(g->*c.size >= c.min)) continue;
      tried_any = true;
      const double carried = g->*c.size;
      json tried = json::array({{{"scale", 1.0}, {"e_t_mm", e_t_best}}});
      std::string best_overlay = overlay;
      double best_scale = 1.0;
      // True when `scale` of the carried size tracks better than the best so far (and becomes it).
      auto better = [&](double scale) -> Result<bool> {
        auto text =
            calibration::overlay_with_size_scaled(cfg, overlay, overlay_path, axis, c.size, scale);
        if (!text) {  // out of the config's range (a dead band over 1 mm): not tried
          tried.push_back(
              {{"scale", scale}, {"e_t_mm", nullptr}, {"error", text.error().to_string()}});
          std::printf("axis %s, %s %.4g x %.2g: not tried: %s\n", axis.c_str(), c.name, carried,
                      scale, text.error().to_string().c_str());
          return false;
        }
        if (Status s = write_text_file(target, text.value()); !s) return s.error();
        if (Status s = reload(api, false); !s) return s.error();
        char what[96];
        std::snprintf(what, sizeof what, "check pattern (axis %s, %s x %.2g)", axis.c_str(), c.name,
                      scale);
        auto e = check_et(api, plan, what);
        if (!e) {
          tried.push_back({{"scale", scale}, {"e_t_mm", nullptr}, {"error", e.error().message}});
          std::printf("axis %s, %s %.4g x %.2g: %s\n", axis.c_str(), c.name, carried, scale,
                      e.error().message.c_str());
          return false;
        }
        tried.push_back({{"scale", scale}, {"e_t_mm", e.value()}});
        std::printf("axis %s, %s %.4g x %.2g: e_t %.4f mm\n", axis.c_str(), c.name, carried, scale,
                    e.value());
        if (!(std::isfinite(e.value()) && e.value() < (1.0 - kSizeTrialMinGain) * e_t_best))
          return false;
        e_t_best = e.value();
        best_scale = scale;
        best_overlay = text.value();
        return true;
      };
      auto half = better(0.5);
      if (!half) return half.error();
      if (half.value()) {
        if (auto none = better(0.0); !none) return none.error();
      } else if (auto more = better(1.5); !more) {
        return more.error();
      }
      report["size_trial"].push_back({{"axis", axis},
                                      {"size", c.name},
                                      {"identified", carried},
                                      {"scale", best_scale},
                                      {"tried", tried}});
      if (best_scale != 1.0) {
        overlay = best_overlay;
        report["e_t_mm"]["after"] = e_t_best;
      }
    }
  if (!tried_any) return overlay;
  // The overlay kept is the one installed.
  if (Status s = write_text_file(target, overlay); !s) return s.error();
  if (Status s = reload(api, false); !s) return s.error();
  return overlay;
}

// The PI gains on the calibrated model (with control.mode pi). The config's gains were designed
// for the config's model; on another machine they can make the loop hurt: on one drawn machine of
// the second simulator the check pattern tracked 0.43 mm with the PI alone against 0.064 open
// loop, and the calibrated feedforward alone 0.026 (docs/calibration.md, "The PI's gains"). The
// config's gains of every calibrated axis are scaled by 1/2, then 1/4 (never 0: below)
// while each tracks the check pattern better than the one before; a scale that faults the machine
// on the check pattern is out. The best is installed (control.axes in the overlay; none when the
// config's own gains win). Gains are never raised: on seed 2 of the second simulator twice the
// config's gains tracked 0.69 mm against 0.0116 (a loop near its limit rings; on a printer, hard).
// Returns the overlay installed.
Result<std::string> choose_pi_gains(Api& api, const Plan& plan, const config::MachineConfig& cfg,
                                    const std::vector<std::string>& axes,
                                    const std::string& overlay, const std::string& overlay_path,
                                    const std::string& target, double e_t_configured,
                                    json& report) {
  auto gains_at = [&](double scale) {
    std::vector<config::AxisGainsConfig> g;
    if (scale == 1.0) return g;  // the config's own
    for (const std::string& a : axes) {
      config::AxisGainsConfig own = cfg.control.gains_for(a);
      own.kp *= scale;
      own.ki_per_s *= scale;
      g.push_back(own);
    }
    return g;
  };
  auto install = [&](double scale) -> Result<std::string> {
    auto text = calibration::overlay_with_gains(cfg, overlay, overlay_path, gains_at(scale));
    if (!text) return text.error();
    if (Status s = write_text_file(target, text.value()); !s) return s.error();
    if (Status s = reload(api, false); !s) return s.error();
    return text.value();
  };
  double best_scale = 1.0, best_mm = e_t_configured;
  json tried = json::array({{{"scale", 1.0}, {"e_t_mm", e_t_configured}}});
  // True when `scale` tracks better than the best so far (and becomes it).
  auto better = [&](double scale) -> Result<bool> {
    if (auto t = install(scale); !t) return t.error();
    char what[64];
    std::snprintf(what, sizeof what, "check pattern (PI gains x %.2g)", scale);
    auto e = check_et(api, plan, what);
    if (!e) {  // a fault on the check pattern (a gain the loop cannot take): not better
      tried.push_back({{"scale", scale}, {"e_t_mm", nullptr}, {"error", e.error().message}});
      std::printf("PI gains x %.2g: %s\n", scale, e.error().message.c_str());
      return false;
    }
    tried.push_back({{"scale", scale}, {"e_t_mm", e.value()}});
    std::printf("PI gains x %.2g: e_t %.4f mm\n", scale, e.value());
    if (!(std::isfinite(e.value()) && e.value() < best_mm)) return false;
    best_mm = e.value();
    best_scale = scale;
    return true;
  };
  // Never 0, the feedforward alone: the check pattern runs at the bed's centre, and off it the
  // integrator takes out what the model misses there (the thesis's Fig. 11: the quadrants differ
  // by calibration and belt irregularities), as it takes out lost steps and drift. Second
  // simulator, seed 1, calibrated: the check pattern tracked best with 0 (0.0027 mm against
  // 0.0034 at 1/4), Table 1's small stars pooled over the four quadrants at 0.0073 / 0.0078 mm
  // with 0 and 0.0047 / 0.0047 with 1/4 (docs/calibration.md, "The PI's gains").
  for (double scale : {0.5, 0.25}) {
    auto b = better(scale);
    if (!b) return b.error();
    if (!b.value()) break;
  }
  auto installed = install(best_scale);
  if (!installed) return installed.error();
  json per_axis = json::object();
  for (const std::string& a : axes) {
    config::AxisGainsConfig g = cfg.control.gains_for(a);
    per_axis[a] = {{"kp", g.kp * best_scale}, {"ki_per_s", g.ki_per_s * best_scale}};
  }
  report["pi_gains"] = {{"scale", best_scale}, {"axes", per_axis}, {"tried", tried}};
  report["e_t_mm"]["after"] = best_mm;
  return installed;
}

struct AxisOutcome {
  std::string axis, recording;
  ident::IdentResult fit;
  // The fit whose model with an effect of calibration::effects_tried_on_the_machine predicts the
  // held-out part best (its augmented model): what calibrate tries on the check pattern. None
  // when no start named one.
  std::optional<ident::IdentResult> with_tried_effects;
  // The other start's fit when its carried model is another model of the axis that predicts the
  // held-out part nearly as well (other_start_worth_trying): what calibrate tries on the check
  // pattern, with what writes that fit's report over the axis's when the machine keeps it.
  std::optional<OtherStart> other_start;
};

bool other_start_worth_trying(const ident::IdentResult& chosen, const ident::IdentResult& other) {
  if (!(other.carried_validation_rms_um <= kOtherStartFactor * chosen.carried_validation_rms_um))
    return false;
  const auto apart = [](double a, double b) {
    return !(a > 0.0 && b > 0.0) || std::fabs(std::log(a / b)) > std::log(1.25);
  };
  const ident::AxisModel& a = chosen.carried;
  const ident::AxisModel& b = other.carried;
  bool effects_differ = false;
  for (int e = 0; e < ident::kEffectCount; ++e) effects_differ |= a.enabled[e] != b.enabled[e];
  return effects_differ || apart(a.k1_n_m, b.k1_n_m) || apart(a.k2_n_m, b.k2_n_m);
}

// carriage_mass_kg: the config's m2 of the axis (0: none configured), the mass identification
// reads forces through (position data fix a force only per unit mass: docs/ident.md, "The force
// needs the carriage's mass"). full_step_mm: the config's drive's full step (0: none configured),
// where identification looks for the drive's own periodic error (ident::FitOptions). start_mm:
// where the job started, in the machine's frame (the daemon's position_mm); the recording's
// commands count from the job's start, and the trace is moved to that frame, so that what the
// overlay places along the travel (the belt's reference, the runout's phase) is where the
// feedforward reads it. NaN: left in the recording's frame.
Result<AxisOutcome> identify_recording(const std::string& axis, const std::string& last_part,
                                       const std::string& dir, double carriage_mass_kg,
                                       double full_step_mm, double start_mm) {
  auto trace = recorder::build_trace(recorder::print_log_parts(last_part), recorder::ExportOptions{});
  if (!trace) return trace.error();
  const recorder::TraceColumns& t = trace.value();
  // A dropped step run shifts the commanded position for the rest of the trace: a model fitted to
  // it would be fitted to a broken trace (27.6 mm RMS was seen), so none is fitted.
  if (t.servo_records_dropped > 0)
    return Error{"the recording " + last_part + " is incomplete: the recorder dropped " +
                 std::to_string(t.servo_records_dropped) +
                 " servo records (its ring was full; `feedloop log info` shows them). Run the "
                 "calibration again (a daemon in --virtual-time never drops; in real time, on a "
                 "less loaded machine)"};
  size_t j = t.joints.size();
  for (size_t i = 0; i < t.joints.size(); ++i)
    if (t.joints[i] == axis) j = i;
  if (j == t.joints.size()) return Error{"the recording " + last_part + " has no joint " + axis};
  // Only the rows the encoder measured (the last report of a print may close after it; the
  // export holds the last reading there).
  recorder::TraceColumns& tw = trace.value();
  const auto [first_s, last_s] = tw.meas_span_s[j];
  if (!(last_s - first_s > 10.0))
    return Error{"the recording " + last_part + " has under 10 s of encoder samples of " + axis};
  const auto row = [&](double s) {
    return static_cast<size_t>(
        std::clamp(s * tw.rate_hz, 0.0, static_cast<double>(tw.time_s.size())));
  };
  const size_t r0 = row(std::ceil(first_s * tw.rate_hz) / tw.rate_hz), r1 = row(last_s) + 1;
  const auto crop = [&](std::vector<double>& v) {
    v = std::vector<double>(v.begin() + static_cast<std::ptrdiff_t>(r0),
                            v.begin() + static_cast<std::ptrdiff_t>(std::min(r1, v.size())));
  };
  for (size_t k = 0; k < tw.joints.size(); ++k) {
    crop(tw.cmd_mm[k]);
    crop(tw.meas_mm[k]);
  }
  crop(tw.time_s);
  for (double& ts : tw.time_s) ts -= static_cast<double>(r0) / tw.rate_hz;
  // The encoder counts from wherever it powered on: its reading is put in the steps' frame at the
  // recording's first sample, where the machine stands still (a job starts from rest).
  std::vector<double>& meas = trace.value().meas_mm[j];
  std::vector<double>& cmd = trace.value().cmd_mm[j];
  if (std::isfinite(start_mm) && !cmd.empty()) {
    const double to_machine_mm = start_mm - cmd.front();
    for (double& u : cmd) u += to_machine_mm;
  }
  const double offset_mm = meas.empty() ? 0.0 : meas.front() - cmd.front();
  for (double& y : meas) y -= offset_mm;
  const std::string csv = dir + "/trace.csv";
  if (Status s = recorder::write_trace_csv(t, csv); !s) return s.error();
  // Two starting points, the thesis's X and Y axes (80 and 21 Hz): the fit is local, and a
  // machine's axis may be either kind whatever its name (the second simulator's Y axis is of the X
  // kind: from the Y start 120.8 um RMS, from the X start 16.3). The better held-out RMS wins.
  // Both fits are scaled to the config's carriage mass when it has one (ident::FitOptions: the
  // positions and names do not change, the forces come out in that carriage's newtons).
  // The start whose model without the effects the feedforward cannot carry predicts the held-out
  // part better wins (calibration::effects_tried_on_the_machine: that model is the overlay's
  // first; the one with them is tried on the check pattern after it).
  ident::FitOptions o;
  o.carriage_mass_kg = carriage_mass_kg;
  o.full_step_mm = full_step_mm;
  o.not_carried = calibration::effects_tried_on_the_machine();
  Result<ident::IdentResult> r = Error{"no fit"};
  std::optional<ident::IdentResult> tried;
  std::optional<ident::IdentResult> other;  // the start that lost on the held-out part
  std::string tried_start;
  auto names_tried = [](const ident::IdentResult& f) {
    for (ident::Effect e : calibration::effects_tried_on_the_machine())
      if (f.augmented.has(e)) return true;
    return false;
  };
  for (const char* start : {"x", "y"}) {
    auto f = ident::identify_axis(start, t.cmd_mm[j], t.meas_mm[j], 1.0 / t.rate_hz, o);
    if (!f) {
      if (!r) r = f.error();
      continue;
    }
    f.value().axis = axis;
    // With the mode, the start whose model with it predicts the held-out part best (it need not
    // be the start whose model without it does).
    if (names_tried(f.value()) &&
        (!tried || f.value().augmented_validation_rms_um < tried->augmented_validation_rms_um)) {
      tried = f.value();
      tried_start = start;
    }
    if (!r || f.value().carried_validation_rms_um < r.value().carried_validation_rms_um) {
      if (r) other = std::move(r.value());
      r = std::move(f);
    } else {
      other = std::move(f.value());
    }
  }
  if (!r) return r.error();
  if (Status s = ident::write_report(dir, r.value(), t.time_s, t.cmd_mm[j], t.meas_mm[j], 1.0 / t.rate_hz, csv); !s)
    return s.error();
  AxisOutcome out;
  out.axis = axis;
  out.recording = last_part;
  out.fit = std::move(r.value());
  if (other && other_start_worth_trying(out.fit, *other))
    out.other_start =
        OtherStart{std::move(*other), last_part,
                   [dir, csv, time_s = t.time_s, cmd = t.cmd_mm[j], meas = t.meas_mm[j],
                    period_s = 1.0 / t.rate_hz](const ident::IdentResult& f) {
                     return ident::write_report(dir, f, time_s, cmd, meas, period_s, csv);
                   }};
  if (tried) {
    // That start fitted again with nothing left out, so that what identification fits on the
    // carried model (the belt's stiffness along the travel) is fitted with the mode in it.
    ident::FitOptions all = o;
    all.not_carried.clear();
    auto f = ident::identify_axis(tried_start, t.cmd_mm[j], t.meas_mm[j], 1.0 / t.rate_hz, all);
    if (f && names_tried(f.value())) {
      f.value().axis = axis;
      out.with_tried_effects = std::move(f.value());
    }
  }
  return out;
}

// Why the fit of `axis` is no model of the machine ("" when it is one): its carried model misses
// the held-out part of the recording by more than a model of a belt axis does anywhere it was
// measured (the simulators' axes: 3-32 um, all seven effects on included), e.g. because the
// carriage lost steps during the excitation (the second drawn first-simulator machine with all
// seven effects: Y left 2.2 mm RMS, its residual jumping by millimetres, and the fit put the scale
// at 0.9).
constexpr double kMaxCredibleHeldOutUm = 200.0;
std::string incredible_fit(const ident::IdentResult& r, const std::string& axis) {
  const double rms = r.carried_validation_rms_um;
  if (rms <= kMaxCredibleHeldOutUm) return "";
  char why[480];
  std::snprintf(why, sizeof why,
                "axis %s is not calibrated: its model misses the held-out part of the recording by "
                "%.0f um RMS (more than %.0f um: the recording is not one a model of the axis "
                "describes; a carriage that lost steps during the excitation leaves jumps of whole "
                "full steps in %s/residual_time.png); the axis keeps the model it had",
                axis.c_str(), rms, kMaxCredibleHeldOutUm, axis.c_str());
  return why;
}

// The overlay's effects of `axis` (what the model carries: calibration/overlay_from_ident.hpp).
json effects_json(const std::vector<config::CalibrationEffect>& effects, const std::string& axis) {
  json list = json::array();
  for (const config::CalibrationEffect& e : effects)
    if (e.axis == axis)
      list.push_back({{"name", e.name}, {"params", e.params}, {"in_model", e.in_model}});
  return list;
}

// The model the machine now prints with (`key`: "after" when kept, "before" when rolled back)
// tracking the check pattern worse than open loop (no feedforward, no loop): the user is better
// served by feedforward.type none, and is told so (a calibration is judged against the model it
// replaces, which may itself be worse than none).
void warn_if_worse_than_open_loop(json& report, const char* key, const std::string& feedforward) {
  if (feedforward == "none") return;  // before and after are the PI alone: no model in the path
  const json& e = report["e_t_mm"];
  if (!e.contains("open_loop") || !e.contains(key) || !e[key].is_number() ||
      !e["open_loop"].is_number())
    return;
  const double ol = e["open_loop"].get<double>(), v = e[key].get<double>();
  if (!(std::isfinite(ol) && std::isfinite(v) && v > ol)) return;
  char w[320];
  std::snprintf(
      w, sizeof w,
      "the model the machine now prints with tracks the check pattern worse than open loop "
      "(%.4f mm against %.4f mm, %+.0f %%): the machine does what the model cannot describe; "
      "feedforward.type none prints better until a calibration fits it",
      v, ol, 100.0 * (v / ol - 1.0));
  report["warning"] = w;
}

std::string report_markdown(const json& j) {
  std::ostringstream m;
  char buf[256];
  m << "# feedloop calibrate\n\n";
  m << "Machine: " << j["machine"].get<std::string>() << "; overlay: `" << j["overlay"].get<std::string>() << "`";
  if (!j["installed"].get<std::string>().empty()) m << ", installed as `" << j["installed"].get<std::string>() << "`";
  m << ".\n\n## Tracking error of the check pattern (circle r 20 mm and star r 5 mm at 90 mm/s)\n\n";
  m << "Before and after: the config's " << j["control"].get<std::string>()
    << "; open loop: the same machine with\n"
    << "control.mode open_loop (the excitation's)."
    << (j.contains("pi_gains") ? " After: with the PI gains chosen below." : "") << "\n\n";
  m << "| run (before and after: the config's control) | e_t mean, mm |\n|---|---|\n";
  const double ol = j["e_t_mm"].value("open_loop", NAN);
  for (const char* k : {"open_loop", "before", "after"}) {
    const double v =
        j["e_t_mm"].contains(k) && j["e_t_mm"][k].is_number() ? j["e_t_mm"][k].get<double>() : NAN;
    if (!std::isfinite(v))
      std::snprintf(buf, sizeof buf, "| %s | not measured |\n", k);
    else if (std::isfinite(ol) && std::string(k) != "open_loop")
      std::snprintf(buf, sizeof buf, "| %s | %.4f (%+.1f %% against open loop) |\n", k, v,
                    100.0 * (v / ol - 1.0));
    else
      std::snprintf(buf, sizeof buf, "| %s | %.4f |\n", k, v);
    m << buf;
  }
  if (j.contains("mode_trial")) {
    const json& t = j["mode_trial"];
    m << "\n## The named mode or periodic error on the machine\n\n";
    std::string named;
    for (const json& e : t.value("effects", json::array()))
      named +=
          (named.empty() ? "" : ", ") + e[1].get<std::string>() + " on " + e[0].get<std::string>();
    m << "Identification named " << (named.empty() ? t["axes"].dump() : named)
      << ". The model with them (an extra mode: a mass on the carriage in the feedforward's "
         "model; a periodic error: the runout the feedforward takes out) is kept only when the "
         "check pattern tracks better with it than with the model fitted without it, both with "
         "the PI gains chosen below.\n\n";
    m << "| model | e_t mean, mm |\n|---|---|\n";
    std::snprintf(buf, sizeof buf, "| without them | %.4f |\n", t["e_t_without_mm"].get<double>());
    m << buf;
    if (t["e_t_with_mm"].is_number())
      std::snprintf(buf, sizeof buf, "| with them | %.4f |\n", t["e_t_with_mm"].get<double>());
    else
      std::snprintf(buf, sizeof buf, "| with them | failed: %.180s |\n",
                    t.value("error", std::string("?")).c_str());
    m << buf;
    m << "\n"
      << (t["kept"].get<bool>() ? "Kept: they are in the model."
                                : "Not kept: the model without them is.")
      << "\n";
  }
  if (j.contains("start_trial")) {
    m << "\n## The other start's model on the machine\n\n";
    m << "Identification fits each axis from two starts (the thesis's X and Y axes) and carries "
         "the model that predicts the recording's held-out part best. When the other start's "
         "model is another model that predicts it nearly as well (within a factor of "
      << kOtherStartFactor
      << "), it is tried on the check pattern with the config's PI gains and kept when it tracks "
         "at least "
      << 100.0 * kOtherStartMinGain << " % better: the recording is not the print.\n\n";
    m << "| axis | held-out RMS of the other start's model, um | e_t before the trial, mm | e_t "
         "with it, mm | kept |\n|---|---|---|---|---|\n";
    for (const json& t : j["start_trial"]) {
      std::snprintf(buf, sizeof buf, "| %s | %.2f | %.4f | ", t["axis"].get<std::string>().c_str(),
                    t["held_out_other_um"].get<double>(), t["e_t_chosen_mm"].get<double>());
      m << buf;
      if (t["e_t_other_mm"].is_number()) {
        std::snprintf(buf, sizeof buf, "%.4f", t["e_t_other_mm"].get<double>());
        m << buf;
      } else {
        m << "failed: " << t.value("error", std::string("?")).substr(0, 180);
      }
      m << " | " << (t["kept"].get<bool>() ? "yes" : "no") << " |\n";
    }
  }
  if (j.contains("size_trial")) {
    m << "\n## The friction forces and dead bands on the machine\n\n";
    m << "Identification's friction is a Dahl bristle and its dead band sharp; a machine's may "
         "follow other laws (a breakaway above the sliding force), and the inverse of the "
         "identified size then pushes at the wrong force, or crosses the wrong gap, at every "
         "reversal. Each carried friction of at least "
      << kSizeTrialMinFrictionN
      << " N and each dead band is tracked on the check pattern at x 1/2 (then 0 while better), "
         "or x 3/2, with the config's PI gains; a scale is kept when it tracks at least "
      << 100.0 * kSizeTrialMinGain << " % better.\n\n";
    m << "| axis | size | identified | scale | e_t mean, mm |\n|---|---|---|---|---|\n";
    for (const json& t : j["size_trial"])
      for (const json& s : t["tried"]) {
        std::snprintf(buf, sizeof buf, "| %s | `%s` | %.4g | %g%s | ",
                      t["axis"].get<std::string>().c_str(), t["size"].get<std::string>().c_str(),
                      t["identified"].get<double>(), s["scale"].get<double>(),
                      s["scale"].get<double>() == t["scale"].get<double>() ? " (kept)" : "");
        m << buf;
        if (s["e_t_mm"].is_number()) {
          std::snprintf(buf, sizeof buf, "%.4f", s["e_t_mm"].get<double>());
          m << buf;
        } else {
          m << "failed: " << s.value("error", std::string("?")).substr(0, 180);
        }
        m << " |\n";
      }
  }
  if (j.contains("pi_gains")) {
    const json& g = j["pi_gains"];
    m << "\n## PI gains on the calibrated model\n\n";
    m << "After: the calibrated model with the config's PI gains of every calibrated axis scaled "
         "by "
      << g["scale"].get<double>() << " (the scale that tracked the check pattern best of 1, 1/2\n"
      << "and 1/4: the loop stays closed), in the overlay's `control.axes`"
      << (j["installed"].get<std::string>().empty() ? " (not kept: see the end)" : "") << ".\n\n";
    m << "| gain scale | e_t mean, mm |\n|---|---|\n";
    for (const json& t : g["tried"]) {
      if (t["e_t_mm"].is_number())
        std::snprintf(buf, sizeof buf, "| %g | %.4f |\n", t["scale"].get<double>(),
                      t["e_t_mm"].get<double>());
      else
        std::snprintf(buf, sizeof buf, "| %g | failed: %.180s |\n", t["scale"].get<double>(),
                      t.value("error", std::string("?")).c_str());
      m << buf;
    }
  }
  m << "\n## Identification per axis (held-out part: the last 30 % of each recording)\n\n";
  m << "| axis | baseline RMS, um | augmented RMS, um | held-out before, um | held-out after, um | effects |\n";
  m << "|---|---|---|---|---|---|\n";
  for (const json& a : j["axes"]) {
    std::string eff;
    for (const json& e : a["effects"]) {
      eff += (eff.empty() ? "" : "; ") + e["name"].get<std::string>() + " (";
      bool first = true;
      for (const auto& [k, v] : e["params"].items()) {
        std::snprintf(buf, sizeof buf, "%s%s %.4g", first ? "" : ", ", k.c_str(), v.get<double>());
        eff += buf;
        first = false;
      }
      eff += e["in_model"].get<bool>() ? ", in the model)" : ", recorded only)";
    }
    if (a.contains("not_calibrated")) eff = "not calibrated (below)";
    std::snprintf(buf, sizeof buf, "| %s | %.2f | %.2f | %.2f | %.2f | %s |\n", a["axis"].get<std::string>().c_str(),
                  a["baseline_rms_um"].get<double>(), a["augmented_rms_um"].get<double>(),
                  a["held_out_before_um"].get<double>(), a["held_out_after_um"].get<double>(),
                  eff.empty() ? "none" : eff.c_str());
    m << buf;
  }
  m << "\nEach axis's report, data files and plots (PNG when gnuplot is installed): `<axis>/report.md`.\n";
  if (j.contains("first_attempts"))
    for (const json& a : j["first_attempts"])
      m << "\n**Excited again at half the acceleration and speed:** axis "
        << a["axis"].get<std::string>() << "'s first recording was refused (its fit left "
        << static_cast<int>(a["held_out_after_um"].get<double>()) << " um RMS held out).\n";
  for (const json& a : j["axes"])
    if (a.contains("not_calibrated"))
      m << "\n**Not calibrated:** " << a["not_calibrated"].get<std::string>() << ".\n";
  if (j.contains("note")) m << "\nNote: " << j["note"].get<std::string>() << ".\n";
  if (j.contains("rolled_back"))
    m << "\n**Not kept:** " << j["rolled_back"].get<std::string>()
      << "; the daemon went back to the calibration it had.\n";
  if (j.contains("warning")) m << "\n**Warning:** " << j["warning"].get<std::string>() << ".\n";
  return m.str();
}

}  // namespace

namespace {

int calibrate(const std::vector<std::string>& args) {
  std::string out_dir = "calibration", api_path, gcode_dir, config_path;
  std::vector<std::string> axes{"x", "y"};
  bool install = true, check_only = false, keep_gains = false;
  uint64_t seed = 1;
  double max_worse_pct = kDefaultMaxWorsePct;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    const bool has = i + 1 < args.size();
    if (a == "--out" && has) out_dir = args[++i];
    else if (a == "--api" && has) api_path = args[++i];
    else if (a == "--write-gcode" && has) gcode_dir = args[++i];
    else if (a == "--config" && has) config_path = args[++i];
    else if (a == "--no-install") install = false;
    else if (a == "--keep-pi-gains")
      keep_gains = true;
    else if (a == "--check-only")
      check_only = true;
    else if (a == "--seed" && has) {
      char* end = nullptr;
      seed = std::strtoull(args[++i].c_str(), &end, 10);
      if (end == nullptr || *end != '\0') {
        std::fprintf(stderr, "feedloop calibrate: --seed takes a whole number\n");
        return 2;
      }
    } else if (a == "--max-worse-pct" && has) {
      char* end = nullptr;
      const std::string& v = args[++i];
      max_worse_pct = std::strtod(v.c_str(), &end);
      if (v.empty() || end == nullptr || *end != '\0' || !std::isfinite(max_worse_pct) ||
          max_worse_pct < 0.0) {
        std::fprintf(stderr,
                     "feedloop calibrate: --max-worse-pct takes a percentage >= 0, not '%s'\n",
                     v.c_str());
        return 2;
      }
    } else if (a == "--axes" && has) {
      axes.clear();
      std::stringstream ss(args[++i]);
      for (std::string s; std::getline(ss, s, ',');) axes.push_back(s);
    } else if (a == "--help" || a == "-h") {
      usage(stdout);
      return 0;
    } else {
      std::fprintf(stderr, "feedloop calibrate: bad argument '%s'\n", a.c_str());
      usage(stderr);
      return 2;
    }
  }
  const auto fail = [](const Error& e) {
    std::fprintf(stderr, "\nfeedloop calibrate: %s\n", e.to_string().c_str());
    return 1;
  };
  if (!gcode_dir.empty()) {  // only the programs
    auto loaded = config::load_machine_config({config_path, "", false});
    if (!loaded) return fail(loaded.error());
    auto plan = make_plan(loaded.value().config, axes, seed);
    if (!plan) return fail(plan.error());
    std::error_code ec;
    fs::create_directories(gcode_dir, ec);
    for (size_t i = 0; i < axes.size(); ++i)
      if (Status s = write_text_file(gcode_dir + "/calibrate_" + axes[i] + ".gcode",
                                     plan.value().programs[i]);
          !s)
        return fail(s.error());
    if (Status s = write_text_file(gcode_dir + "/calibrate_check.gcode",
                                   plan.value().check_start + plan.value().check);
        !s)
      return fail(s.error());
    std::printf("wrote the calibration programs and the check pattern into %s\n", gcode_dir.c_str());
    return 0;
  }
  if (api_path.empty()) {
    auto p = config::expand_path("${RUNTIME_DIR}/api.sock", config::path_vars_from_environment());
    if (p) api_path = p.value();
  }
  Api api;
  if (!api.open(api_path)) return fail(Error{"cannot connect to the daemon's API socket " + api_path});
  auto info = api.call("info");
  if (!info) return fail(info.error());
  // The daemon's config (the overlay is laid over it) and the model it runs now (its calibration
  // included), loaded as the daemon loads them.
  std::string cfg_path = info.value().value("config", "(embedded default)");
  if (cfg_path == "(embedded default)") cfg_path.clear();
  auto base = config::load_machine_config({cfg_path, "", false});
  if (!base) return fail(base.error());
  const config::MachineConfig& cfg = base.value().config;
  auto running =
      config::load_machine_config({cfg_path, info.value().value("calibration", ""), false});
  auto plan = make_plan(running ? running.value().config : cfg, axes, seed);
  if (!plan) return fail(plan.error());
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (ec) return fail(Error{"cannot create " + out_dir + ": " + ec.message()});

  const std::string feedforward = info.value().value("feedforward", "");
  json report{{"machine", info.value().value("name", "")},
              {"control", "control " + info.value().value("control", "?") + ", feedforward " +
                              info.value().value("feedforward", "?")},
              {"axes", json::array()}};
  auto before =
      check_et(api, plan.value(), check_only ? "check pattern" : "check pattern (before)");
  if (!before) return fail(before.error());
  if (check_only) {
    if (!std::isfinite(before.value()))
      return fail(Error{
          "the machine measured no e_t (it does with control.mode pi or maneuver, not open loop)"});
    std::printf("e_t of the check pattern: %.4f mm (control %s, feedforward %s)\n", before.value(),
                info.value().value("control", "?").c_str(),
                info.value().value("feedforward", "?").c_str());
    return 0;
  }
  if (!std::isfinite(before.value()))
    std::fprintf(stderr,
                 "calibrate: the machine measures no e_t with control.mode open_loop: the report "
                 "has none\n");
  report["e_t_mm"]["before"] = before.value();
  // The excitation runs open loop: the steps are then the whole motor command (with the loops on,
  // the device adds corrections the recording has only every 10 ms).
  // The same pattern open loop without feedforward (the steps are the plan): what the loop and the
  // feedforward start from.
  if (Status s = reload(api, true, true); !s) return fail(s.error());
  std::string overlay;
  Status excited = Status{};
  if (auto ol = check_et(api, plan.value(), "check pattern (open loop)"); ol)
    report["e_t_mm"]["open_loop"] = ol.value();
  else
    excited = ol.error();
  // The excitation open loop with the configured feedforward: its inverse puts the model's modes
  // into the steps (with F = 1 the planner's moves excite less: first simulator X held out 17.9
  // against 3.0 um, second simulator seed 7 e_t after 0.0259 against 0.0135 mm).
  if (Status s = reload(api, true); excited && !s) excited = s;
  std::vector<std::string> calibrated;  // the axes whose fit the overlay carries
  // The calibrated axes whose identification named an effect that goes into the model only when
  // the check pattern tracks better with it (calibration::effects_tried_on_the_machine), with
  // their recordings.
  std::vector<std::pair<ident::IdentResult, std::string>> to_try;
  // The calibrated axes whose other start's fit is another model nearly as good on the recording.
  std::vector<OtherStart> others;
  // One run of axis i's program (gentle: at kGentle of the acceleration and speed) and its fit.
  auto excite = [&](size_t i, bool gentle) -> Result<AxisOutcome> {
    if (Status h = home_if_needed(api); !h) return h.error();
    // Where the program starts, in the machine's frame (the recording counts from there).
    double start_mm = std::numeric_limits<double>::quiet_NaN();
    if (auto st = api.call("status"); st && st.value().contains("position_mm")) {
      const json& p = st.value()["position_mm"];
      if (p.contains(axes[i]) && p[axes[i]].is_number()) start_mm = p[axes[i]].get<double>();
    }
    auto rec = run_job(api, "feedloop_calibrate_" + axes[i] + ".gcode",
                       gentle ? plan.value().gentle_programs[i] : plan.value().programs[i],
                       "calibration program, axis " + axes[i] +
                           (gentle ? ", at half the acceleration and speed" : ""));
    if (!rec) return rec.error();
    const std::string dir = out_dir + "/" + axes[i];
    fs::create_directories(dir, ec);
    std::fprintf(stderr, "calibrate: identifying axis %s ...\n", axes[i].c_str());
    // The mass the user's config gives the carriage (the base config: an overlay's m2 is a
    // calibration's, not a weighing).
    const config::GantryModelConfig* g = cfg.model.gantry_for(axes[i]);
    return identify_recording(axes[i], rec.value(), dir, g != nullptr ? g->m2_kg : 0.0,
                              g != nullptr ? g->stepper.full_step_mm() : 0.0, start_mm);
  };
  for (size_t i = 0; i < axes.size() && excited; ++i) {
    auto got = excite(i, false);
    std::string why = got ? incredible_fit(got.value().fit, axes[i]) : "";
    const bool gentle = got && !why.empty();
    if (gentle) {
      // Once more, gentler: a carriage that loses steps at the axis's limits may not at half.
      std::fprintf(stderr, "warning: %s; exciting it again at half the acceleration and speed\n",
                   why.c_str());
      const ident::IdentResult& r0 = got.value().fit;
      report["first_attempts"].push_back({{"axis", axes[i]},
                                          {"recording", got.value().recording},
                                          {"held_out_after_um", r0.augmented_validation_rms_um},
                                          {"not_calibrated", why}});
      got = excite(i, true);
      why = got ? incredible_fit(got.value().fit, axes[i]) : "";
    }
    if (!got) {
      excited = got.error();
      break;
    }
    const ident::IdentResult& r = got.value().fit;
    report["axes"].push_back({{"axis", axes[i]},
                              {"recording", got.value().recording},
                              {"baseline_rms_um", r.baseline_rms_um},
                              {"augmented_rms_um", r.augmented_rms_um},
                              {"held_out_before_um", r.baseline_validation_rms_um},
                              {"held_out_after_um", r.augmented_validation_rms_um},
                              {"effects", json::array()}});
    report["axes"].back()["warnings"] = r.warnings;
    if (gentle) report["axes"].back()["gentle"] = kGentle;
    std::printf("axis %s: residual RMS %.2f -> %.2f um (held out %.2f -> %.2f um), effects: %zu\n", axes[i].c_str(),
                r.baseline_rms_um, r.augmented_rms_um, r.baseline_validation_rms_um, r.augmented_validation_rms_um,
                r.effects.size());
    for (const std::string& w : r.warnings)
      std::fprintf(stderr, "warning: axis %s: %s\n", axes[i].c_str(), w.c_str());
    if (!why.empty()) {
      // Not a model of this machine: the axis keeps the one it had (its effects are not listed).
      report["axes"].back()["not_calibrated"] = why;
      std::fprintf(stderr, "warning: %s\n", why.c_str());
      continue;
    }
    auto merged = calibration::merge_overlay(
        cfg, overlay, out_dir + "/calibration.yaml", calibration::with_carried_model(r),
        "feedloop calibrate, recording " + got.value().recording);
    if (!merged) {
      excited = merged.error();
      break;
    }
    overlay = merged.value();
    calibrated.push_back(axes[i]);
    if (got.value().with_tried_effects)
      to_try.emplace_back(*got.value().with_tried_effects, got.value().recording);
    if (got.value().other_start) others.push_back(*got.value().other_start);
  }
  if (excited && calibrated.empty())
    excited = Error{"no axis was calibrated: every fit was refused (" + out_dir +
                    "/report.json says why); the daemon keeps its model"};
  if (excited) {  // the effects as the overlay has them
    auto applied = config::apply_calibration_text(cfg, overlay, out_dir + "/calibration.yaml");
    if (!applied)
      excited = applied.error();
    else
      for (json& a : report["axes"])
        a["effects"] = effects_json(applied.value().effects, a["axis"].get<std::string>());
  }
  const std::string overlay_path = out_dir + "/calibration.yaml";
  const std::string target = info.value().value("calibration_path", "");
  report["overlay"] = overlay_path;
  report["installed"] = "";
  report["e_t_mm"]["after"] = nullptr;
  if (excited) {
    if (Status s = write_text_file(overlay_path, overlay); !s) excited = s;
  }
  if (excited && install && target.empty())
    std::fprintf(stderr, "calibrate: the daemon reads no calibration (--no-calibration): not installed\n");
  std::optional<std::string> previous;  // the overlay the daemon had (nullopt: none)
  if (excited && install && !target.empty()) {
    // The daemon's overlay is kept to roll back to: one that cannot be read is not replaced.
    auto had = read_existing_text_file(target);
    if (!had) {
      excited = Error{"the daemon's calibration " + had.error().to_string() +
                      ": not replaced (the new overlay is in " + overlay_path + ")"};
    } else {
      previous = had.value();
      if (Status s = write_text_file(target, overlay); !s)
        excited = s;
      else
        report["installed"] = target;
    }
  }
  // Back to the configured control (with the new calibration when installed), also after a failure.
  if (Status s = reload(api, false); !s) return fail(s.error());
  if (!excited) return fail(excited.error());
  if (!report["installed"].get<std::string>().empty()) {
    // The daemon goes back to what it had when the calibrated model does not print (a fit the
    // machine cannot follow) or prints worse than the model it replaces; the report says so.
    auto roll_back = [&](const std::string& why) {
      std::error_code rm;
      if (previous)
        (void)write_text_file(target, *previous);
      else
        fs::remove(target, rm);
      const Status back = reload(api, false);
      report["installed"] = "";
      report["rolled_back"] = why;
      warn_if_worse_than_open_loop(report, "before", feedforward);
      (void)write_text_file(out_dir + "/report.json", report.dump(2) + "\n");
      (void)write_text_file(out_dir + "/report.md", report_markdown(report));
      if (report.contains("warning"))
        std::fprintf(stderr, "warning: %s\n", report["warning"].get<std::string>().c_str());
      return fail(Error{why + "\nthe calibrated model was not kept: " +
                        (previous ? "the previous calibration is back"
                                  : "the daemon runs without a calibration") +
                        (back ? std::string() : " (reload failed: " + back.error().message + ")") +
                        "; " + overlay_path + " and " + out_dir + "/report.md say what was found"});
    };
    auto after = check_et(api, plan.value(), "check pattern (after)");
    if (!after)
      return roll_back("with the calibrated model the check pattern failed: " +
                       after.error().message);
    report["e_t_mm"]["after"] = after.value();
    double after_mm = after.value();
    // The overlay a trial on the machine kept: saved, its effects in the report, its e_t the
    // figure the next step starts from.
    auto adopt = [&](const std::string& kept) -> Status {
      overlay = kept;
      if (Status s = write_text_file(overlay_path, overlay); !s) return s;
      if (auto applied = config::apply_calibration_text(cfg, overlay, overlay_path); applied)
        for (json& a : report["axes"])
          a["effects"] = effects_json(applied.value().effects, a["axis"].get<std::string>());
      after_mm = report["e_t_mm"]["after"].get<double>();
      return Status{};
    };
    if (!others.empty()) {
      // The other start's model of an axis on the check pattern, with the config's PI gains
      // (the gains are chosen below, on the model kept); kept when it tracks better.
      auto kept = try_other_starts_on_the_machine(api, plan.value(), cfg, others, overlay,
                                                  overlay_path, target, after_mm, report);
      if (!kept) return roll_back("trying the other start's model failed: " + kept.error().message);
      if (Status s = adopt(kept.value()); !s) return fail(s.error());
    }
    {
      // The carried friction forces and dead bands on the check pattern, with the config's PI
      // gains (the gains are chosen below, on the sizes kept); a scale kept when it tracks better.
      auto kept = try_sizes_on_the_machine(api, plan.value(), cfg, calibrated, overlay,
                                           overlay_path, target, after_mm, report);
      if (!kept) return roll_back("trying the carried sizes failed: " + kept.error().message);
      if (Status s = adopt(kept.value()); !s) return fail(s.error());
    }
    if (info.value().value("control", "") == "pi" && !keep_gains) {
      // after_mm: the e_t with the config's gains (x 1) on the model kept so far.
      auto chosen = choose_pi_gains(api, plan.value(), cfg, calibrated, overlay, overlay_path,
                                    target, after_mm, report);
      if (!chosen) return roll_back("choosing the PI gains failed: " + chosen.error().message);
      overlay = chosen.value();
      if (Status s = write_text_file(overlay_path, overlay); !s) return fail(s.error());
      after_mm = report["e_t_mm"]["after"].get<double>();
    }
    if (!to_try.empty()) {
      // The model with the named mode(s) on the check pattern, with the PI gains chosen above;
      // kept when it tracks better.
      auto tried = try_effects_on_the_machine(api, plan.value(), cfg, to_try, overlay, overlay_path,
                                              target, after_mm, report);
      if (!tried)
        return roll_back("trying the named effects on the machine failed: " +
                         tried.error().message);
      if (Status s = adopt(tried.value()); !s) return fail(s.error());
    }
    const json& e_t_before = report["e_t_mm"]["before"];
    if (e_t_before.is_number() && std::isfinite(e_t_before.get<double>()) &&
        after_mm > (1.0 + 0.01 * max_worse_pct) * e_t_before.get<double>()) {
      char why[160];
      std::snprintf(why, sizeof why,
                    "with the calibrated model the check pattern's e_t is %.4f mm against %.4f mm "
                    "before",
                    after_mm, e_t_before.get<double>());
      return roll_back(why);
    }
  }
  warn_if_worse_than_open_loop(report, "after", feedforward);
  if (feedforward == "none")
    report["note"] = "the config's feedforward is none: prints do not use the calibrated model "
                     "(feedforward.type: lpv uses it)";
  if (Status s = write_text_file(out_dir + "/report.json", report.dump(2) + "\n"); !s)
    return fail(s.error());
  if (Status s = write_text_file(out_dir + "/report.md", report_markdown(report)); !s)
    return fail(s.error());
  if (report["e_t_mm"]["before"].is_number() &&
      std::isfinite(report["e_t_mm"]["before"].get<double>()))
    std::printf("e_t of the check pattern: before %.4f mm",
                report["e_t_mm"]["before"].get<double>());
  if (report["e_t_mm"]["after"].is_number() &&
      std::isfinite(report["e_t_mm"]["after"].get<double>()))
    std::printf(", after %.4f mm (%+.1f %%)", report["e_t_mm"]["after"].get<double>(),
                100.0 * (report["e_t_mm"]["after"].get<double>() / report["e_t_mm"]["before"].get<double>() - 1.0));
  if (report["e_t_mm"].contains("open_loop") && report["e_t_mm"]["after"].is_number() &&
      std::isfinite(report["e_t_mm"]["open_loop"].get<double>()))
    std::printf("; open loop %.4f mm (after: %+.1f %% against it)",
                report["e_t_mm"]["open_loop"].get<double>(),
                100.0 * (report["e_t_mm"]["after"].get<double>() /
                             report["e_t_mm"]["open_loop"].get<double>() -
                         1.0));
  std::printf("\nwrote %s, %s/report.md and report.json%s\n", overlay_path.c_str(), out_dir.c_str(),
              report["installed"].get<std::string>().empty() ? "" : "; installed and loaded");
  if (report.contains("note")) std::printf("note: %s\n", report["note"].get<std::string>().c_str());
  if (report.contains("warning"))
    std::printf("warning: %s\n", report["warning"].get<std::string>().c_str());
  return 0;
}

}  // namespace

// An answer of another shape than this feedloop's daemon gives (an older daemon, a broken reply)
// is a clear error, not an abort.
int calibrate_command(const std::vector<std::string>& args) {
  try {
    return calibrate(args);
  } catch (const nlohmann::json::exception& e) {
    std::fprintf(
        stderr,
        "\nfeedloop calibrate: the daemon's answer is not what this feedloop expects (%s)\n",
        e.what());
    return 1;
  }
}

}  // namespace feedloop::cli
