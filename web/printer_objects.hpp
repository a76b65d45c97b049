// Klipper's printer objects (https://www.klipper3d.org/Status_Reference.html) built from
// feedloop's status, plus feedloop's own: feedloop_servo (period, cycles, deadline misses,
// wake-up latency percentiles and histogram), feedloop_links (each MCU link), feedloop_tracking
// (e_t now, mean, max, per layer; lost-step events).
#pragma once

#include <nlohmann/json.hpp>

#include "web/printer_backend.hpp"
#include "web/telemetry.hpp"

namespace feedloop::web {

struct ObjectInputs {
  const PrinterInfo& info;
  const engine::MachineStatus& machine;
  const engine::ServoStatus& servo;
  const JobStatus& job;
  const TrackingTelemetry& tracking;
  const std::string& gcodes_dir;  // virtual_sdcard.file_path is absolute in Klipper
  const planner::ObjectLabels& objects;  // exclude_object
};

nlohmann::json printer_objects(const ObjectInputs& in);
// The power (0..1) of the first hotend (Klipper's `extruder`) and the first bed (`heater_bed`).
struct HeaterPowers {
  double hotend = 0.0, bed = 0.0;
};
HeaterPowers heater_powers(const engine::MachineStatus& s);
// Klipper's webhooks.state: ready, or shutdown after an emergency stop or a machine fault.
std::string webhooks_state(const engine::MachineStatus& s);
// The G-code commands the console offers (Klipper's gcode.commands, for autocomplete).
const nlohmann::json& gcode_commands();

}  // namespace feedloop::web
