// The config's heaters and fans -> the thermal loop's options (DESIGN.md: the config is read once,
// at the edge). heater_sensor() is the one place a config sensor becomes thermal::SensorParams.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "config/machine_config.hpp"
#include "core/result.hpp"
#include "engine/shared_heater_port.hpp"
#include "engine/thermal_loop.hpp"
#include "thermal/sensor.hpp"

namespace feedloop::engine {

thermal::SensorParams heater_sensor(const config::HeaterConfig& h);
ThermalOptions thermal_options(const config::MachineConfig& cfg);
// The config's heaters and fans (their indices) whose `mcu:` is `board`, in file order: the
// board's channels 0, 1, .. ("" gives those that name no board).
struct BoardChannels {
  std::vector<int> heaters, fans;
  bool empty() const { return heaters.empty() && fans.empty(); }
};
BoardChannels board_channels(const config::MachineConfig& cfg, const std::string& board);
// True when the heaters and fans name their boards (heater_mcus, or motion MCUs by mcu:).
bool heaters_on_boards(const config::MachineConfig& cfg);
// The thermal loop of the config's machine; nullptr when it has no heaters and no fans. Heaters
// and fans run on the boards their `mcu:` names: a board of heater_mcus (its own McuSession:
// serial, usb, or a simulated board in-process) or a motion MCU of mcus (its session is the motion
// bridge's: `ports`, the executor's heater_ports(), carry the messages; without them such a config
// is refused). With no board named, on the simulated printer's heater MCU
// (make_simulated_heater_link), which needs every motion MCU mock (else refused with a message).
Result<std::unique_ptr<ThermalLoop>> make_thermal_loop(const config::MachineConfig& cfg,
                                                       const SharedHeaterPorts* ports = nullptr);

}  // namespace feedloop::engine
