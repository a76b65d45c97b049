#include "engine/executor_factory.hpp"

#include "engine/position_executor.hpp"

namespace feedloop::engine {

Result<std::unique_ptr<CommandExecutor>> make_executor(const config::MachineConfig& /*cfg*/) {
  return std::unique_ptr<CommandExecutor>(std::make_unique<PositionExecutor>());
}

MachineOptions machine_options(const config::MachineConfig& cfg) {
  MachineOptions o;
  o.servo_rate_hz = cfg.servo.rate_hz;
  o.realtime_priority = cfg.servo.realtime_priority;
  o.lock_memory = cfg.servo.lock_memory;
  return o;
}

}  // namespace feedloop::engine
