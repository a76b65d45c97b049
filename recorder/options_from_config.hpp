// RecorderOptions from the printer config: the [recorder] section (directory with ${STATE_DIR}
// expanded), the config text for the file header, and per joint its name, steps/mm, encoder
// resolution and the clock of the MCU that drives it.
#pragma once

#include <string>
#include <vector>

#include "config/config.hpp"
#include "config/machine_config.hpp"
#include "core/result.hpp"
#include "recorder/recorder.hpp"

namespace feedloop::recorder {

// `joint_names`: the engine's joint order (engine::joint_names(cfg)); every name must be an axis
// of the config.
Result<RecorderOptions> recorder_options_from_config(const config::MachineConfig& cfg, std::string config_yaml,
                                                     const std::vector<std::string>& joint_names,
                                                     const config::PathVars& vars);

}  // namespace feedloop::recorder
