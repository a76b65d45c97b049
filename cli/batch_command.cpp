#include "cli/batch_command.hpp"

#include <nlohmann/json.hpp>

#include <cstdio>
#include <fstream>

#include "cli/progress.hpp"
#include "config/config.hpp"
#include "engine/batch.hpp"

namespace feedloop::cli {
namespace {

void usage() {
  std::fputs(
      "usage: feedloop batch FILE.gcode [--config CFG.yaml] [--json OUT.json] [--quiet]\n"
      "  Translates FILE through the whole pipeline in virtual time (no hardware) and prints a\n"
      "  summary. Without --config the embedded simulated Cartesian printer is used.\n",
      stderr);
}

std::string format_duration(double s) {
  char buf[64];
  const int h = static_cast<int>(s / 3600), m = static_cast<int>(s / 60) % 60;
  std::snprintf(buf, sizeof buf, "%dh %02dm %04.1fs", h, m, s - 3600.0 * h - 60.0 * m);
  return buf;
}

}  // namespace

int batch_command(const std::vector<std::string>& args) {
  std::string file, config_path, json_path;
  bool quiet = false;
  for (size_t i = 0; i < args.size(); ++i) {
    if (args[i] == "--config" && i + 1 < args.size()) config_path = args[++i];
    else if (args[i] == "--json" && i + 1 < args.size()) json_path = args[++i];
    else if (args[i] == "--quiet") quiet = true;
    else if (args[i] == "--help") { usage(); return 0; }
    else if (file.empty() && args[i].rfind("--", 0) != 0) file = args[i];
    else { std::fprintf(stderr, "feedloop batch: unexpected argument '%s'\n", args[i].c_str()); usage(); return 2; }
  }
  if (file.empty()) { usage(); return 2; }
  auto cfg = config_path.empty() ? Result<config::MachineConfig>(config::default_config())
                                 : config::load_config_file(config_path);
  if (!cfg) {
    std::fprintf(stderr, "feedloop batch: invalid config:\n%s\n", cfg.error().to_string().c_str());
    return 1;
  }
  Progress progress("batch");
  engine::BatchOptions opt;
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
  std::printf("  wall time         %.3f s (%.0f lines/s, %.1f M steps/s)\n", s.wall_s,
              s.lines / std::max(s.wall_s, 1e-9), s.total_steps / std::max(s.wall_s, 1e-9) / 1e6);
  if (s.check_failures) std::printf("  COMPRESSION CHECK FAILURES: %llu\n", static_cast<unsigned long long>(s.check_failures));
  for (const std::string& m : s.messages) std::printf("  warning: %s\n", m.c_str());
  if (s.rejected > static_cast<int64_t>(s.messages.size()))
    std::printf("  ... and %lld more rejected lines\n", static_cast<long long>(s.rejected - static_cast<int64_t>(s.messages.size())));
  if (!json_path.empty()) {
    nlohmann::json j{{"file", s.file}, {"lines", s.lines}, {"commands", s.commands},
                     {"rejected", s.rejected}, {"moves", s.moves}, {"print_time_s", s.print_time_s},
                     {"total_steps", s.total_steps}, {"wire_bytes", s.wire_bytes},
                     {"wire_bytes_per_step", s.wire_bytes_per_step}, {"wall_s", s.wall_s},
                     {"messages", s.messages}};
    for (int k = 0; k < engine::kJoints; ++k) {
      const auto& js = s.joints[static_cast<size_t>(k)];
      j["joints"][s.joint_names[static_cast<size_t>(k)]] = {{"steps", js.steps}, {"runs", js.runs},
          {"batches", js.batches}, {"max_step_rate_hz", js.max_step_rate_hz}};
    }
    std::ofstream(json_path) << j.dump(2) << "\n";
  }
  return s.check_failures == 0 ? 0 : 1;
}

}  // namespace feedloop::cli
