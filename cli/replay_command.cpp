// `feedloop replay` and `feedloop record` (see replay_command.hpp).
#include "cli/replay_command.hpp"

#include <cstdio>
#include <fstream>
#include <sstream>

#include "config/config.hpp"
#include "config/file_text.hpp"
#include "gcode/file_lines.hpp"
#include "recorder/replay.hpp"

namespace feedloop::cli {
namespace {

void replay_usage(std::FILE* out) {
  std::fputs(
      "usage: feedloop replay LOG... [--config FILE] [--keep-log DIR]\n"
      "  re-runs the G-code of a flight-recorder log (its parts, in order) through the motion\n"
      "  pipeline against the simulator in virtual time, and compares with the recording: planned\n"
      "  moves, time anchors, the commanded step stream (bit for bit) and the encoder data\n"
      "  (recorded - simulated: RMS and max per joint, the model's residual on that print)\n"
      "  --config FILE   the machine config to replay with (default: the one in the log header)\n"
      "  --keep-log DIR  write the replay's own log into DIR and keep it\n"
      "exit status: 0 bit-identical step stream, 1 different, 2 usage or unreadable input\n",
      out);
}

void record_usage(std::FILE* out) {
  std::fputs(
      "usage: feedloop record FILE.gcode --dir DIR [--config FILE] [--name NAME]\n"
      "  runs a G-code file through the motion pipeline against the simulator in virtual time with\n"
      "  the flight recorder on, and writes the log into DIR (the config must use mock MCUs)\n",
      out);
}

}  // namespace

int replay_command(const std::vector<std::string>& args) {
  std::vector<std::string> logs;
  recorder::ReplayOptions o;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "--help" || a == "-h") {
      replay_usage(stdout);
      return 0;
    }
    if ((a == "--config" || a == "--keep-log") && i + 1 < args.size()) {
      (a == "--config" ? o.config_path : o.out_dir) = args[++i];
      continue;
    }
    if (a.rfind("--", 0) == 0) {
      std::fprintf(stderr, "feedloop replay: unknown or incomplete option '%s'\n", a.c_str());
      replay_usage(stderr);
      return 2;
    }
    logs.push_back(a);
  }
  if (logs.empty()) {
    replay_usage(stderr);
    return 2;
  }
  auto rep = recorder::replay_print(logs, o);
  if (!rep) {
    std::fprintf(stderr, "feedloop replay: %s\n", rep.error().to_string().c_str());
    return 2;
  }
  std::fputs(rep->to_text().c_str(), stdout);
  return rep->steps_identical() ? 0 : 1;
}

int record_command(const std::vector<std::string>& args) {
  std::string gcode, dir, config_path, name;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "--help" || a == "-h") {
      record_usage(stdout);
      return 0;
    }
    if ((a == "--dir" || a == "--config" || a == "--name") && i + 1 < args.size()) {
      (a == "--dir" ? dir : a == "--config" ? config_path : name) = args[++i];
      continue;
    }
    if (a.rfind("--", 0) == 0 || !gcode.empty()) {
      std::fprintf(stderr, "feedloop record: unexpected argument '%s'\n", a.c_str());
      record_usage(stderr);
      return 2;
    }
    gcode = a;
  }
  if (gcode.empty() || dir.empty()) {
    record_usage(stderr);
    return 2;
  }
  std::string yaml(config::default_config_yaml());
  if (!config_path.empty()) {
    auto text = config::read_config_file_text(config_path, "config file");
    if (!text) {
      std::fprintf(stderr, "feedloop record: %s\n", text.error().to_string().c_str());
      return 2;
    }
    yaml = std::move(text.value());
  }
  auto cfg = config::load_config_text(yaml, config_path.empty() ? "(embedded default)" : config_path);
  if (!cfg) {
    std::fprintf(stderr, "feedloop record: %s\n", cfg.error().to_string().c_str());
    return 2;
  }
  // Streamed in chunks with the line cap of the other readers: a line without an end (a binary
  // file, /dev/zero) is held to 256 KiB, not read into memory whole.
  std::vector<std::string> lines;
  int64_t first_too_long = 0;
  const Status read = gcode::for_each_file_line(gcode, [&](const gcode::SplitLine& l) {
    if (l.too_long && first_too_long == 0) first_too_long = l.number;
    std::string_view t = l.text;
    if (!t.empty() && t.back() == '\r') t.remove_suffix(1);
    lines.emplace_back(t);
  });
  if (!read) {
    std::fprintf(stderr, "feedloop record: %s\n", read.error().to_string().c_str());
    return 2;
  }
  if (first_too_long != 0) {
    std::fprintf(stderr, "feedloop record: %s:%lld: line longer than %zu bytes: not G-code\n",
                 gcode.c_str(), static_cast<long long>(first_too_long),
                 gcode::LineSplitter::kDefaultMaxLineBytes);
    return 2;
  }
  if (name.empty()) {
    name = gcode.substr(gcode.find_last_of('/') + 1);
    if (const size_t dot = name.rfind('.'); dot != std::string::npos && dot > 0) name.resize(dot);
  }
  auto run = recorder::record_virtual_print(*cfg, yaml, lines, dir, name);
  if (!run) {
    std::fprintf(stderr, "feedloop record: %s\n", run.error().to_string().c_str());
    return 1;
  }
  std::printf("recorded %llu commands (%llu rejected), %.3f s of virtual time, %llu motion starts, %llu encoder samples\n",
              static_cast<unsigned long long>(run->commands), static_cast<unsigned long long>(run->rejected),
              run->virtual_s, static_cast<unsigned long long>(run->anchors),
              static_cast<unsigned long long>(run->encoder_samples));
  if (!run->first_error.empty()) std::printf("first rejected: %s\n", run->first_error.c_str());
  for (const std::string& l : run->logs) std::printf("log: %s\n", l.c_str());
  return run->rejected == 0 ? 0 : 1;
}

}  // namespace feedloop::cli
