// The config's heaters and fans -> the thermal loop's options (DESIGN.md: the config is read once,
// at the edge). heater_sensor() is the one place a config sensor becomes thermal::SensorParams.
#pragma once

#include <memory>

#include "config/machine_config.hpp"
#include "core/result.hpp"
#include "engine/thermal_loop.hpp"
#include "thermal/sensor.hpp"

namespace feedloop::engine {

thermal::SensorParams heater_sensor(const config::HeaterConfig& h);
ThermalOptions thermal_options(const config::MachineConfig& cfg);
// The thermal loop of the config's machine; nullptr when it has no heaters and no fans. The
// simulated printer's heaters (every MCU mock, or none) run on its heater MCU, reached through an
// McuSession and frames (make_simulated_heater_link); a config with serial/usb MCUs is refused
// (heaters on a motion MCU's link are not wired yet; docs/heaters.md).
Result<std::unique_ptr<ThermalLoop>> make_thermal_loop(const config::MachineConfig& cfg);

}  // namespace feedloop::engine
