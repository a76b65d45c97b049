// Where a machine's config comes from: the printer config (a file, or the embedded simulated
// printer) with the calibration overlay laid over it (config/calibration.hpp). The daemon loads it
// so at start and at every reload (SIGHUP, M999), so a calibration written while it runs is used
// from the next reload on; `feedloop batch --calibration` the same way.
#pragma once

#include <string>
#include <vector>

#include "config/config.hpp"
#include "core/result.hpp"

namespace feedloop::config {

struct ConfigSource {
  std::string config_path;       // empty: the embedded default config
  std::string calibration_path;  // empty: none
  bool calibration_required = false;  // false: a missing file is no calibration (the default path)
};

struct LoadedConfig {
  MachineConfig config;
  std::string calibration;            // the overlay applied ("" when none)
  std::vector<std::string> changes;   // what it changed, one line per key
};

// The default overlay: ${STATE_DIR}/calibration.yaml (path_vars_from_environment).
std::string default_calibration_path();

// Errors: the config's, the overlay's (with its file:line:column), or a required overlay missing.
Result<LoadedConfig> load_machine_config(const ConfigSource& source);

}  // namespace feedloop::config
