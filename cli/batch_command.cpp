#include "cli/batch_command.hpp"

#include <nlohmann/json.hpp>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "cli/progress.hpp"
#include "config/config.hpp"
#include "config/config_source.hpp"
#include "engine/batch.hpp"
#include "engine/config_mapping.hpp"
#include "engine/maneuver_executor.hpp"
#include "engine/sim_run.hpp"
#include "gcode/file_lines.hpp"

namespace feedloop::cli {
namespace {

void usage() {
  std::fputs(
      "usage: feedloop batch FILE.gcode [--config CFG.yaml] [--json OUT.json] [--quiet] [--threads "
      "auto|1|2]\n"
      "       feedloop batch FILE.gcode [--config CFG.yaml] --simulate [--json OUT.json]\n"
      "       feedloop batch FILE.gcode [--config CFG.yaml] --export-trace TRACE.csv\n"
      "  (each also takes --calibration OVERLAY.yaml: a calibration overlay laid over the config,\n"
      "  as feedloopd does; docs/calibration.md)\n"
      "  Translates FILE through the whole pipeline in virtual time (no hardware) and prints a\n"
      "  summary. Without --config the embedded simulated Cartesian printer is used. --threads 2\n"
      "  shares the stepping of the joints with a second thread, 1 does all on one; auto "
      "(default)\n"
      "  takes 2 when the process may run on two cores. The output is the same either way.\n"
      "  --simulate runs FILE on the simulated printer of the config (its mock MCUs, plants and\n"
      "  control law) and prints what the machine did: lost-step events, the tracking error e_t\n"
      "  from the encoders, faults, steps the plant lost (ground truth). Exit 1 on any of them.\n"
      "  --export-trace runs FILE on the simulated printer of the config (its mock MCUs, the\n"
      "  control law it configures) and writes every servo period's commanded motor positions and\n"
      "  encoder readings as trace CSV v1 (DESIGN.md), for replay on another simulator or ident;\n"
      "  extra columns <axis>_ref_mm hold the planned positions (ref - meas: the tracking "
      "error).\n",
      stderr);
}

std::string format_duration(double s) {
  char buf[64];
  const int h = static_cast<int>(s / 3600), m = static_cast<int>(s / 60) % 60;
  std::snprintf(buf, sizeof buf, "%dh %02dm %04.1fs", h, m, s - 3600.0 * h - 60.0 * m);
  return buf;
}

// The G-code file's lines (false, with a message, when it cannot be read or a line is longer than
// the 256 KiB every reader caps lines at).
bool read_lines(const std::string& file, std::vector<std::string>& lines) {
  int64_t too_long_at = 0;
  const Status read = gcode::for_each_file_line(file, [&](const gcode::SplitLine& l) {
    if (l.too_long && too_long_at == 0) too_long_at = l.number;
    lines.emplace_back(l.text);
  });
  if (!read) {
    std::fprintf(stderr, "feedloop batch: %s\n", read.error().to_string().c_str());
    return false;
  }
  if (too_long_at > 0) {
    std::fprintf(stderr, "feedloop batch: %s:%lld: line longer than %zu bytes: not G-code\n",
                 file.c_str(), static_cast<long long>(too_long_at),
                 gcode::LineSplitter::kDefaultMaxLineBytes);
    return false;
  }
  return true;
}

// Trace CSV v1 of a simulated run: per joint with steps, the commanded motor position (the steps
// the command puts out by then: n = round(u steps_per_mm)) and the encoder reading; then, as
// extra columns (the contract lets readers ignore them), each joint's planned position r, so
// that r - meas is the tracking error e_t sample by sample.
int export_trace(const std::string& file, const config::MachineConfig& cfg, const std::string& trace_path,
                 bool quiet) {
  std::vector<std::string> lines;
  if (!read_lines(file, lines)) return 1;
  std::ofstream out(trace_path);
  if (!out) {
    std::fprintf(stderr, "feedloop batch: cannot write %s\n", trace_path.c_str());
    return 1;
  }
  const auto names = engine::joint_names(cfg);
  const auto spm = engine::steps_per_mm(cfg);
  std::vector<int> joints;  // the motion joints with an encoder
  for (int j = 0; j < 3; ++j) {
    const config::AxisConfig* a = cfg.axis(names[static_cast<size_t>(j)]);
    const bool encoder = a != nullptr ? a->encoder.has_value() : cfg.kinematics == config::Kinematics::delta;
    if (spm[static_cast<size_t>(j)] > 0.0 && encoder) joints.push_back(j);
  }
  if (joints.empty()) {
    std::fprintf(stderr, "feedloop batch: the config's axes have no encoders: nothing to measure\n");
    return 1;
  }
  out << "# source=feedloop batch --export-trace\n# gcode=" << file << "\n# sample_rate_hz=" << cfg.servo.rate_hz
      << "\n# machine=" << cfg.name << "\ntime_s";
  for (int j : joints) out << ',' << names[static_cast<size_t>(j)] << "_cmd_mm," << names[static_cast<size_t>(j)] << "_meas_mm";
  for (int j : joints) out << ',' << names[static_cast<size_t>(j)] << "_ref_mm";
  out << '\n';
  uint64_t rows = 0;
  double t0_s = NAN;  // machine time of the first sample: the trace's time 0
  engine::SimRunOptions o;
  o.keep_samples = false;
  o.timeout_s = 1e7;
  o.on_sample = [&](const engine::SimRunSample& s) {
    char buf[64];
    if (std::isnan(t0_s)) t0_s = s.servo.host_time_s;
    std::snprintf(buf, sizeof buf, "%.6f", s.servo.host_time_s - t0_s);
    out << buf;
    for (int j : joints) {
      const size_t i = static_cast<size_t>(j);
      const double cmd = std::round(s.servo.command_mm[i] * spm[i]) / spm[i];
      std::snprintf(buf, sizeof buf, ",%.6f,%.6f", cmd, s.servo.encoder_mm[i]);
      out << buf;
    }
    for (int j : joints) {
      std::snprintf(buf, sizeof buf, ",%.6f", s.servo.desired_mm[static_cast<size_t>(j)]);
      out << buf;
    }
    out << '\n';
    ++rows;
  };
  auto r = engine::run_simulated(cfg, lines, o);
  if (!r) {
    std::fprintf(stderr, "feedloop batch: %s\n", r.error().to_string().c_str());
    return 1;
  }
  out.close();
  if (!quiet)
    std::printf("trace: %s (%llu samples at %.0f Hz, %llu commands, %llu rejected, %llu lost full steps)\n",
                trace_path.c_str(), static_cast<unsigned long long>(rows), cfg.servo.rate_hz,
                static_cast<unsigned long long>(r->commands), static_cast<unsigned long long>(r->rejected),
                static_cast<unsigned long long>(r->lost_full_steps[0] + r->lost_full_steps[1] + r->lost_full_steps[2]));
  if (!r->error.empty()) std::fprintf(stderr, "feedloop batch: %s\n", r->error.c_str());
  return r->error.empty() ? 0 : 1;
}

// Writes `j` to `path`; false (with a message) when the file cannot be written.
bool write_json_file(const std::string& path, const nlohmann::json& j) {
  std::ofstream out(path);
  out << j.dump(2) << "\n";
  out.flush();
  if (!out) {
    std::fprintf(stderr, "feedloop batch: cannot write %s: %s\n", path.c_str(), std::strerror(errno));
    return false;
  }
  return true;
}

// The file on the config's simulated printer, in virtual time: the machine's own figures (what
// the daemon's status shows at the end of a print) and the plant's ground truth.
int simulate(const std::string& file, const config::MachineConfig& cfg, const std::string& config_name,
             const std::string& json_path, bool quiet) {
  std::vector<std::string> lines;
  if (!read_lines(file, lines)) return 1;
  Progress progress("simulate");
  engine::SimRunOptions o;
  o.keep_samples = false;
  o.timeout_s = 1e7;
  if (!quiet) o.on_progress = [&](double f) { progress.update(f); };
  const auto t0 = std::chrono::steady_clock::now();
  auto r = engine::run_simulated(cfg, lines, o);
  if (!quiet) progress.finish();
  if (!r) {
    std::fprintf(stderr, "feedloop batch: %s\n", r.error().to_string().c_str());
    return 1;
  }
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  int64_t lost_full_steps = 0;
  for (int64_t n : r->lost_full_steps) lost_full_steps += n;
  std::printf("simulated print: %s (config: %s)\n", file.c_str(), config_name.c_str());
  std::printf("  lines             %zu (%llu commands, %llu rejected)\n", lines.size(),
              static_cast<unsigned long long>(r->commands), static_cast<unsigned long long>(r->rejected));
  std::printf("  print time        %s (%.1f s), simulated in %.1f s\n", format_duration(r->motion_time_s).c_str(),
              r->motion_time_s, wall_s);
  std::printf("  tracking error    e_t from the encoders: mean %.4f mm, max %.4f mm (%llu samples)\n",
              r->tracking_error_mean_mm, r->tracking_error_max_mm,
              static_cast<unsigned long long>(r->tracking_error_samples));
  std::printf("  lost steps        %llu events (plant: %lld full steps lost)\n",
              static_cast<unsigned long long>(r->lost_step_events), static_cast<long long>(lost_full_steps));
  // Where the machine saw them (the first few): a detection the plant does not confirm is the
  // detector's, and its recovery moved the carriage.
  const auto joint_names = engine::joint_names(cfg);
  int shown = 0;
  for (const engine::ServoEvent& e : r->events) {
    if (e.kind != engine::ServoEventKind::kLostSteps || shown >= 8) continue;
    ++shown;
    std::printf(
        "    at %.3f s print time, joint %s: %+.4f mm\n", e.print_time_s,
        e.joint >= 0 && e.joint < 4 ? joint_names[static_cast<size_t>(e.joint)].c_str() : "?",
        e.size_mm);
  }
  std::printf("  faults            %llu%s%s\n", static_cast<unsigned long long>(r->faults),
              r->error.empty() ? "" : ", first error: ", r->error.c_str());
  if (!json_path.empty()) {
    nlohmann::json j{{"file", file}, {"config", config_name}, {"lines", lines.size()},
                     {"commands", r->commands}, {"rejected", r->rejected},
                     {"print_time_s", r->motion_time_s}, {"wall_s", wall_s},
                     {"lost_step_events", r->lost_step_events}, {"lost_full_steps", lost_full_steps},
                     {"tracking_error_mm", {{"mean", r->tracking_error_mean_mm},
                                            {"max", r->tracking_error_max_mm},
                                            {"samples", r->tracking_error_samples}}},
                     {"faults", r->faults}, {"error", r->error}};
    if (!write_json_file(json_path, j)) return 1;
  }
  const bool clean = r->error.empty() && r->rejected == 0 && r->faults == 0 && r->lost_step_events == 0 &&
                     lost_full_steps == 0;
  return clean ? 0 : 1;
}

// A DC-servo machine (drive: dc_servo): the G-code through engine::Machine with the maneuvering
// executor in virtual time, and the path-following figures.
int maneuver_batch(const std::string& file, const config::MachineConfig& cfg, bool quiet,
                   const std::string& json_path) {
  std::vector<std::string> lines;
  if (!read_lines(file, lines)) return 1;
  auto r = engine::run_maneuver_virtual(cfg, lines, 1e7);
  if (!r) {
    std::fprintf(stderr, "feedloop batch: %s\n", r.error().to_string().c_str());
    return 1;
  }
  if (!quiet) {
    std::printf("batch summary (DC-servo, output maneuvering): %s\n", file.c_str());
    std::printf("  lines             %llu executed, %llu rejected%s%s\n", static_cast<unsigned long long>(r->commands),
                static_cast<unsigned long long>(r->rejected), r->first_error.empty() ? "" : ": ",
                r->first_error.c_str());
    std::printf("  moves             %llu (%llu path segments followed)\n", static_cast<unsigned long long>(r->moves),
                static_cast<unsigned long long>(r->segments_entered));
    std::printf("  time              %.2f s of machine time (%.2f s on the path)\n", r->virtual_s, r->path_time_s);
    std::printf("  path              %.1f mm\n", r->path_mm);
    std::printf("  max cross-track   %.2f um (IAE %.4f mm s)\n", r->max_cross_track_mm * 1e3, r->iae_cross_track_mm_s);
    std::printf("  max error         %.2f um, max voltage %.1f V\n", r->max_error_mm * 1e3, r->max_voltage_v);
    std::printf("  end position      X %.3f Y %.3f Z %.3f mm%s\n", r->end_mm[0], r->end_mm[1], r->end_mm[2],
                r->faulted ? " (stopped on a tracking fault)" : "");
  }
  if (!json_path.empty()) {
    const nlohmann::json j{{"file", file},
                           {"drive", "dc_servo"},
                           {"commands", r->commands},
                           {"rejected", r->rejected},
                           {"first_error", r->first_error},
                           {"moves", r->moves},
                           {"segments_entered", r->segments_entered},
                           {"machine_time_s", r->virtual_s},
                           {"path_time_s", r->path_time_s},
                           {"path_mm", r->path_mm},
                           {"max_cross_track_mm", r->max_cross_track_mm},
                           {"iae_cross_track_mm_s", r->iae_cross_track_mm_s},
                           {"max_error_mm", r->max_error_mm},
                           {"max_voltage_v", r->max_voltage_v},
                           {"end_mm", {r->end_mm[0], r->end_mm[1], r->end_mm[2]}},
                           {"faulted", r->faulted}};
    if (!write_json_file(json_path, j)) return 1;
  }
  return r->faulted ? 1 : 0;
}

}  // namespace

int batch_command(const std::vector<std::string>& args) {
  std::string file, config_path, json_path, trace_path, calibration_path;
  bool quiet = false, sim = false;
  int threads = 0;  // auto
  for (size_t i = 0; i < args.size(); ++i) {
    if (args[i] == "--config" && i + 1 < args.size()) config_path = args[++i];
    else if (args[i] == "--calibration" && i + 1 < args.size())
      calibration_path = args[++i];
    else if (args[i] == "--threads" && i + 1 < args.size()) {
      const std::string& v = args[++i];
      if (v != "auto" && v != "1" && v != "2") {
        std::fprintf(stderr, "feedloop batch: --threads must be auto, 1 or 2, not '%s'\n",
                     v.c_str());
        return 2;
      }
      threads = v == "auto" ? 0 : v == "1" ? 1 : 2;
    } else if (args[i] == "--json" && i + 1 < args.size())
      json_path = args[++i];
    else if (args[i] == "--quiet") quiet = true;
    else if (args[i] == "--simulate") sim = true;
    else if (args[i] == "--export-trace" && i + 1 < args.size()) trace_path = args[++i];
    else if (args[i] == "--help") { usage(); return 0; }
    else if (file.empty() && args[i].rfind("--", 0) != 0) file = args[i];
    else { std::fprintf(stderr, "feedloop batch: unexpected argument '%s'\n", args[i].c_str()); usage(); return 2; }
  }
  if (file.empty()) { usage(); return 2; }
  auto loaded = config::load_machine_config({config_path, calibration_path, true});
  if (!loaded) {
    std::fprintf(stderr, "feedloop batch: invalid config:\n%s\n",
                 loaded.error().to_string().c_str());
    return 1;
  }
  if (!quiet)
    for (const std::string& c : loaded.value().changes)
      std::fprintf(stderr, "calibration %s: %s\n", calibration_path.c_str(), c.c_str());
  const config::MachineConfig* cfg = &loaded.value().config;
  if (cfg->drive == config::Drive::dc_servo) return maneuver_batch(file, *cfg, quiet, json_path);
  if (!trace_path.empty()) return export_trace(file, *cfg, trace_path, quiet);
  if (sim) return simulate(file, *cfg, config_path.empty() ? "embedded default" : config_path, json_path, quiet);
  Progress progress("batch");
  engine::BatchOptions opt;
  opt.threads = threads;
  if (!quiet) opt.on_progress = [&](double f) { progress.update(f); };
  auto sum = engine::run_batch(file, *cfg, opt);
  if (!quiet) progress.finish();
  if (!sum) {
    std::fprintf(stderr, "feedloop batch: %s\n", sum.error().to_string().c_str());
    return 1;
  }
  const engine::BatchSummary& s = *sum;
  std::printf("batch summary: %s (config: %s)\n", s.file.c_str(),
              config_path.empty() ? "embedded default" : config_path.c_str());
  std::printf("  lines             %lld (%lld commands, %lld rejected, %lld unknown)\n",
              static_cast<long long>(s.lines), static_cast<long long>(s.commands),
              static_cast<long long>(s.rejected), static_cast<long long>(s.unknown_commands));
  std::printf("  moves             %llu\n", static_cast<unsigned long long>(s.moves));
  std::printf("  print time        %s (%.1f s)\n", format_duration(s.print_time_s).c_str(), s.print_time_s);
  std::printf("  %-6s %12s %10s %9s %14s\n", "joint", "steps", "runs", "batches", "max rate");
  for (int j = 0; j < engine::kJoints; ++j) {
    const auto& js = s.joints[static_cast<size_t>(j)];
    std::printf("  %-6s %12llu %10llu %9llu %11.1f kHz\n", s.joint_names[static_cast<size_t>(j)].c_str(),
                static_cast<unsigned long long>(js.steps), static_cast<unsigned long long>(js.runs),
                static_cast<unsigned long long>(js.batches), js.max_step_rate_hz / 1e3);
  }
  std::printf("  total steps       %llu\n", static_cast<unsigned long long>(s.total_steps));
  std::printf("  bytes on the wire %llu (%.3f bytes/step, step-time bound %.1f us)\n",
              static_cast<unsigned long long>(s.wire_bytes), s.wire_bytes_per_step,
              cfg->stepgen.max_step_error_us);
  std::printf("  wall time         %.3f s (%.0f lines/s, %.1f M steps/s, %d thread%s)\n", s.wall_s,
              s.lines / std::max(s.wall_s, 1e-9), s.total_steps / std::max(s.wall_s, 1e-9) / 1e6,
              s.threads, s.threads == 1 ? "" : "s");
  if (s.check_failures) std::printf("  COMPRESSION CHECK FAILURES: %llu\n", static_cast<unsigned long long>(s.check_failures));
  for (const std::string& m : s.messages) std::printf("  warning: %s\n", m.c_str());
  if (s.rejected > static_cast<int64_t>(s.messages.size()))
    std::printf("  ... and %lld more rejected lines\n", static_cast<long long>(s.rejected - static_cast<int64_t>(s.messages.size())));
  if (!json_path.empty()) {
    nlohmann::json j{{"file", s.file},
                     {"lines", s.lines},
                     {"commands", s.commands},
                     {"rejected", s.rejected},
                     {"moves", s.moves},
                     {"print_time_s", s.print_time_s},
                     {"total_steps", s.total_steps},
                     {"wire_bytes", s.wire_bytes},
                     {"wire_bytes_per_step", s.wire_bytes_per_step},
                     {"wall_s", s.wall_s},
                     {"cpu_s", s.cpu_s},
                     {"threads", s.threads},
                     {"messages", s.messages}};
    for (int k = 0; k < engine::kJoints; ++k) {
      const auto& js = s.joints[static_cast<size_t>(k)];
      j["joints"][s.joint_names[static_cast<size_t>(k)]] = {{"steps", js.steps}, {"runs", js.runs},
          {"batches", js.batches}, {"max_step_rate_hz", js.max_step_rate_hz}};
    }
    if (!write_json_file(json_path, j)) return 1;
  }
  return s.check_failures == 0 ? 0 : 1;
}

}  // namespace feedloop::cli
