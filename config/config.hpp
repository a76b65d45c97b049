// Loading, validating and writing printer configs. One YAML file describes a printer (schema:
// config/README.md); a bad file yields an Error listing every problem as "file:line:col: message"
// and never a half-filled MachineConfig.
//
//   auto cfg = feedloop::config::load_config_file("printer.yaml");
//   if (!cfg) { std::cerr << cfg.error().to_string() << "\n"; return 1; }
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "config/machine_config.hpp"
#include "core/result.hpp"

namespace feedloop::config {

// Reads and validates a config file. On failure the Error's `where` is the first problem and its
// message continues with one "file:line:col: message" line per further problem.
Result<MachineConfig> load_config_file(const std::string& path);

// Same for text already in memory; `source_name` is the file name used in messages.
Result<MachineConfig> load_config_text(std::string_view yaml, const std::string& source_name);

// Every problem in a config, one Error each (empty: the config is valid).
std::vector<Error> check_config_text(std::string_view yaml, const std::string& source_name);

// The simulated Cartesian printer compiled into the library (config/examples/cartesian_sim.yaml).
std::string_view default_config_yaml();
const MachineConfig& default_config();

// Writes a config back as YAML that loads to an equal MachineConfig (every key written out).
std::string to_yaml(const MachineConfig& config);

// Directories that path values may refer to as ${RUNTIME_DIR} and ${STATE_DIR}.
struct PathVars {
  std::string runtime_dir;  // sockets, pty link
  std::string state_dir;    // recordings
};

// From systemd's RUNTIME_DIRECTORY / STATE_DIRECTORY, else XDG_RUNTIME_DIR / XDG_STATE_HOME
// (+ "/feedloop"), else a per-user directory under /tmp.
PathVars path_vars_from_environment();

// Replaces ${RUNTIME_DIR} and ${STATE_DIR}; any other ${...} is an error.
Result<std::string> expand_path(std::string_view path, const PathVars& vars);

}  // namespace feedloop::config
