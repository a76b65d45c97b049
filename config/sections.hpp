// Internal to the config library: one reader per top-level section, each filling its part of a
// MachineConfig and reporting problems to Diagnostics. Called in order by loader.cpp; later sections
// may check references to earlier ones (an MCU's axes must exist). Not part of the public API.
#pragma once

#include <map>
#include <string>
#include <string_view>

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
// One axis's entry of model.gantry: the six Eq. 13 parameters (`six`: required in a config,
// optional in a calibration overlay, which changes only what it names), friction and the stepper
// section.
void read_gantry_axis(MapReader& g, GantryModelConfig& m, Need six, Diagnostics& diag);
// Whether model.gantry may have an entry `name` (a Cartesian or CoreXY machine's axis); reports why
// not.
bool gantry_axis_known(const MachineConfig& cfg, const std::string& name, const YAML::Mark& where,
                       Diagnostics& diag);
void read_stepgen_mcus(MapReader& root, MachineConfig& cfg, Marks& marks, Diagnostics& diag);
void read_simulator(MapReader& root, MachineConfig& cfg, Diagnostics& diag);
void read_io(MapReader& root, MachineConfig& cfg, Diagnostics& diag);
void read_thermal(MapReader& root, MachineConfig& cfg, Diagnostics& diag);

// False, with the first byte that is not UTF-8 reported at its line and column, when `yaml` is not
// valid UTF-8 (YAML text is Unicode; yaml-cpp does not check).
bool utf8_or_report(std::string_view yaml, Diagnostics& diag);

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
