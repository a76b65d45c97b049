// From the printer config (config/) to the parameters of each pipeline stage. One place, so the
// daemon, batch mode, replay and the benchmarks build identical pipelines from one file.
#pragma once

#include <array>
#include <string>

#include "config/machine_config.hpp"
#include "planner/config.hpp"

namespace feedloop::engine {

// Joint order everywhere in the engine: the three motors of the kinematics (x y z, or the delta
// carriages A B C), then the extruder.
inline constexpr int kJoints = 4;
std::array<std::string, kJoints> joint_names(const config::MachineConfig& cfg);

planner::PlannerConfig planner_config(const config::MachineConfig& cfg);
std::array<double, kJoints> steps_per_mm(const config::MachineConfig& cfg);

}  // namespace feedloop::engine
