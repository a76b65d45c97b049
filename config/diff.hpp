// Which top-level sections differ between two configs, e.g. to decide what a SIGHUP reload may
// apply while idle (a changed `mcus` or `kinematics` needs the transports rebuilt).
#pragma once

#include <string>
#include <vector>

#include "config/machine_config.hpp"

namespace feedloop::config {

// Names of the top-level keys whose values differ ("axes", "planner", "mcus", ...), in schema
// order; empty when the configs are equal.
std::vector<std::string> changed_sections(const MachineConfig& before, const MachineConfig& after);

}  // namespace feedloop::config
