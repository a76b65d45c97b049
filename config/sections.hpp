// Internal to the config library: one reader per top-level section, each filling its part of a
// MachineConfig and reporting problems to Diagnostics. Called in order by loader.cpp; later sections
// may check references to earlier ones (an MCU's axes must exist). Not part of the public API.
#pragma once

#include <map>
#include <string>

#include <yaml-cpp/yaml.h>

#include "config/diagnostics.hpp"
#include "config/machine_config.hpp"
#include "config/map_reader.hpp"

namespace feedloop::config::detail {

// Where things were written, for cross-field messages that point at the right line.
struct Marks {
  YAML::Mark root;
  YAML::Mark kinematics;
  YAML::Mark drive;
  YAML::Mark axes;
  std::map<std::string, YAML::Mark> axis;  // by axis name
  YAML::Mark delta;
  YAML::Mark mcus;
  YAML::Mark control;
  YAML::Mark feedforward;
  YAML::Mark stepgen;
};

void read_axes(MapReader& root, MachineConfig& cfg, Marks& marks, Diagnostics& diag,
               bool kinematics_known);
void read_delta(MapReader& root, MachineConfig& cfg, Marks& marks, Diagnostics& diag);
void read_planner(MapReader& root, MachineConfig& cfg, Diagnostics& diag);
void read_extruder(MapReader& root, MachineConfig& cfg, Diagnostics& diag);
void read_servo_control(MapReader& root, MachineConfig& cfg, Diagnostics& diag);
void read_model(MapReader& root, MachineConfig& cfg, Diagnostics& diag);
void read_stepgen_mcus(MapReader& root, MachineConfig& cfg, Marks& marks, Diagnostics& diag);
void read_simulator(MapReader& root, MachineConfig& cfg, Diagnostics& diag);
void read_io(MapReader& root, MachineConfig& cfg, Diagnostics& diag);
void read_thermal(MapReader& root, MachineConfig& cfg, Diagnostics& diag);

// Checks that need the whole machine: every axis driven by exactly one MCU, delta reachability.
void check_machine(const MachineConfig& cfg, const Marks& marks, Diagnostics& diag);

// The axis names a kinematics requires and allows.
const std::vector<std::string>& required_axes(Kinematics k);
const std::vector<std::string>& allowed_axes(Kinematics k);

// An MCU entry's transport, serial and usb keys (mcus[], heater_mcus[]).
void read_transport(MapReader& m, McuConfig& mcu, Diagnostics& diag);

// Reads an optional list of axis names (`key`) and checks each names an existing axis.
void read_axis_refs(MapReader& m, const char* key, const MachineConfig& cfg,
                    std::vector<std::string>& out, Diagnostics& diag);

}  // namespace feedloop::config::detail
