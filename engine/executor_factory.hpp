// Builds the command executor for a machine config: the motion pipeline (interpreter, lookahead,
// joint segments) for the configured kinematics.
#pragma once

#include <memory>

#include "config/machine_config.hpp"
#include "core/result.hpp"
#include "engine/machine.hpp"

namespace feedloop::engine {

Result<std::unique_ptr<CommandExecutor>> make_executor(const config::MachineConfig& cfg);

MachineOptions machine_options(const config::MachineConfig& cfg);

}  // namespace feedloop::engine
