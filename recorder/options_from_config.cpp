// recorder_options_from_config (see options_from_config.hpp).
#include "recorder/options_from_config.hpp"

#include <algorithm>

namespace feedloop::recorder {

Result<RecorderOptions> recorder_options_from_config(const config::MachineConfig& cfg, std::string config_yaml,
                                                     const std::vector<std::string>& joint_names,
                                                     const config::PathVars& vars) {
  RecorderOptions o;
  o.config = cfg.recorder;
  if (cfg.recorder.enabled) {
    auto dir = config::expand_path(cfg.recorder.directory, vars);
    if (!dir) return Error{"recorder.directory: " + dir.error().message, dir.error().where};
    o.config.directory = *dir;
  }
  o.config_yaml = std::move(config_yaml);
  if (joint_names.size() > static_cast<size_t>(kMaxJoints))
    return Error{"recorder: at most " + std::to_string(kMaxJoints) + " joints can be recorded", {}};
  for (const std::string& name : joint_names) {
    const config::AxisConfig* axis = cfg.axis(name);
    if (!axis) return Error{"recorder: joint '" + name + "' is not an axis of the config", {}};
    JointInfo j;
    j.name = name;
    j.steps_per_mm = axis->steps_per_mm;
    j.encoder_resolution_mm = axis->encoder ? axis->encoder->resolution_um * 1e-3 : 0.0;
    j.clock_hz = cfg.stepgen.mcu_clock_hz;
    for (const config::McuConfig& m : cfg.mcus)
      if (std::find(m.axes.begin(), m.axes.end(), name) != m.axes.end()) j.clock_hz = m.clock_hz;
    o.joints.push_back(j);
  }
  return o;
}

}  // namespace feedloop::recorder
