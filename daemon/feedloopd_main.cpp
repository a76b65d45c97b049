// feedloopd: the feedloop motion daemon.
//
//   feedloopd [--config FILE] [--calibration FILE | --no-calibration] [--check-config] [--log-level
//   LEVEL] [--version]
//
// Without --config it runs the embedded default: the simulated Cartesian printer.
#include <spdlog/sinks/basic_file_sink.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <cstring>
#include <iostream>
#include <string>

#include "config/config.hpp"
#include "config/config_source.hpp"
#include "daemon/daemon.hpp"

namespace {

void usage(std::FILE* out) {
  std::fputs(
      "usage: feedloopd [--config FILE] [--calibration FILE | --no-calibration] [--check-config] "
      "[--log-level LEVEL] [--virtual-time]\n"
      "  --config FILE      printer config (YAML); default: the embedded simulated printer\n"
      "  --check-config     validate the config (and the calibration), print every problem, exit\n"
      "  --calibration FILE the calibration overlay to lay over the config (feedloop calibrate,\n"
      "                     feedloop ident fit --overlay); default: ${STATE_DIR}/calibration.yaml\n"
      "                     when it exists\n"
      "  --no-calibration   the config alone\n"
      "  --log-level LEVEL  trace|debug|info|warn|error (overrides logging.level)\n"
      "  --virtual-time     simulated printers: run the machine in virtual time, as fast as\n"
      "                     the CPU allows (tests, demos)\n"
      "Channels: a Unix socket speaking the Marlin host protocol, a pty that looks like a\n"
      "Marlin serial port, and a JSON-RPC 2.0 (NDJSON) API socket; see the README.\n",
      out);
}

void setup_logging(const feedloop::config::LoggingConfig& cfg, const std::string& level_override) {
  std::vector<spdlog::sink_ptr> sinks;
  sinks.push_back(std::make_shared<spdlog::sinks::stderr_color_sink_mt>());
  if (!cfg.file.empty()) {
    const auto path = feedloop::config::expand_path(cfg.file, feedloop::config::path_vars_from_environment());
    try {
      if (!path) throw spdlog::spdlog_ex(path.error().message);
      sinks.push_back(std::make_shared<spdlog::sinks::basic_file_sink_mt>(*path));
    } catch (const spdlog::spdlog_ex& e) {
      std::fprintf(stderr, "feedloopd: cannot open log file %s: %s\n", cfg.file.c_str(), e.what());
    }
  }
  auto logger = std::make_shared<spdlog::logger>("feedloopd", sinks.begin(), sinks.end());
  logger->set_pattern("%Y-%m-%d %H:%M:%S.%e %^%l%$ %v");
  spdlog::level::level_enum lvl = spdlog::level::from_str(
      level_override.empty() ? std::string(spdlog::level::to_string_view(
                                   static_cast<spdlog::level::level_enum>(cfg.level)).data())
                             : level_override);
  logger->set_level(lvl);
  logger->flush_on(spdlog::level::warn);
  spdlog::set_default_logger(logger);
}

}  // namespace

int main(int argc, char** argv) {
  std::string config_path, log_level;
  feedloop::config::ConfigSource source;
  source.calibration_path = feedloop::config::default_calibration_path();
  bool check_only = false;
  bool virtual_time = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--config" && i + 1 < argc) {
      config_path = argv[++i];
    } else if (a == "--calibration" && i + 1 < argc) {
      source.calibration_path = argv[++i];
      source.calibration_required = true;
    } else if (a == "--no-calibration") {
      source.calibration_path.clear();
    } else if (a == "--log-level" && i + 1 < argc) {
      log_level = argv[++i];
      // spdlog reads an unknown name as "off": a typo would silence the log.
      if (log_level != "trace" && log_level != "debug" && log_level != "info" &&
          log_level != "warn" && log_level != "error") {
        std::fprintf(stderr,
                     "feedloopd: --log-level must be trace, debug, info, warn or error, not '%s'\n",
                     log_level.c_str());
        return 2;
      }
    } else if (a == "--virtual-time") {
      virtual_time = true;
    } else if (a == "--check-config") {
      check_only = true;
    } else if (a == "--version") {
      std::puts("feedloopd 0.1.0");
      return 0;
    } else if (a == "--help" || a == "-h") {
      usage(stdout);
      return 0;
    } else {
      std::fprintf(stderr, "feedloopd: unknown argument '%s'\n", a.c_str());
      usage(stderr);
      return 2;
    }
  }
  source.config_path = config_path;
  auto loaded = feedloop::config::load_machine_config(source);
  if (!loaded) {
    std::fprintf(stderr, "feedloopd: invalid config:\n%s\n", loaded.error().to_string().c_str());
    return 1;
  }
  feedloop::config::MachineConfig* cfg = &loaded.value().config;
  if (check_only) {
    std::printf("%s: ok ('%s')\n", config_path.empty() ? "(embedded default)" : config_path.c_str(),
                cfg->name.c_str());
    if (!loaded.value().calibration.empty())
      std::printf("%s: ok (%zu changes)\n", loaded.value().calibration.c_str(),
                  loaded.value().changes.size());
    return 0;
  }
  setup_logging(cfg->logging, log_level);
  for (const std::string& c : loaded.value().changes)
    spdlog::info("calibration {}: {}", loaded.value().calibration, c);
  feedloop::daemon::DaemonOptions options{config_path, 5.0, virtual_time};
  options.calibration_path = source.calibration_path;
  options.calibration_required = source.calibration_required;
  feedloop::daemon::Daemon daemon(std::move(*cfg), options);
  daemon.set_calibration_applied(loaded.value().calibration);
  if (feedloop::Status s = daemon.start(); !s) {
    spdlog::critical("cannot start: {}", s.error().to_string());
    return 1;
  }
  const int rc = daemon.run();
  spdlog::info("feedloopd stopped");
  spdlog::shutdown();
  return rc;
}
