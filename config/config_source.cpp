// The printer config with its calibration overlay (config_source.hpp).
#include "config/config_source.hpp"

#include <sys/stat.h>

#include "config/calibration.hpp"

namespace feedloop::config {

std::string default_calibration_path() {
  auto p = expand_path("${STATE_DIR}/calibration.yaml", path_vars_from_environment());
  return p ? p.value() : std::string();
}

Result<LoadedConfig> load_machine_config(const ConfigSource& source) {
  auto base = source.config_path.empty() ? Result<MachineConfig>(default_config())
                                         : load_config_file(source.config_path);
  if (!base) return base.error();
  LoadedConfig out;
  struct stat st {};
  if (source.calibration_path.empty() || (!source.calibration_required && ::stat(source.calibration_path.c_str(), &st) != 0)) {
    out.config = std::move(base.value());
    return out;
  }
  auto applied = apply_calibration_file(base.value(), source.calibration_path);
  if (!applied) return applied.error();
  out.config = std::move(applied.value().config);
  out.calibration = source.calibration_path;
  out.changes = std::move(applied.value().changes);
  return out;
}

}  // namespace feedloop::config
