// Builds the command executor for a machine config: the motion pipeline (interpreter, lookahead,
// joint segments) for the configured kinematics.
#pragma once

#include <memory>

#include "config/machine_config.hpp"
#include "core/result.hpp"
#include "engine/machine.hpp"
#include "engine/motion_executor.hpp"

namespace feedloop::engine {

Result<std::unique_ptr<CommandExecutor>> make_executor(const config::MachineConfig& cfg);

class McuBridge;
// The motion executor and, when the config has MCUs, the bridge behind it (kept for inspection:
// the simulated plants, the step timing; engine/sim_run.cpp). make_executor() is this, unwrapped.
struct MotionStack {
  std::unique_ptr<MotionExecutor> executor;
  std::shared_ptr<McuBridge> bridge;  // nullptr: no MCUs (an ideal plant)
};
Result<MotionStack> make_motion_stack(const config::MachineConfig& cfg);
// `observer` (optional, e.g. the flight recorder's recorder::EngineRecording) sees every step run,
// position reset and time anchor of the step pipeline; it must outlive the stack.
Result<MotionStack> make_motion_stack(const config::MachineConfig& cfg, const MotionOptions& options,
                                      StepObserver* observer = nullptr);
// The executor's options from the config (lead times).
MotionOptions motion_options(const config::MachineConfig& cfg);

MachineOptions machine_options(const config::MachineConfig& cfg);

}  // namespace feedloop::engine
