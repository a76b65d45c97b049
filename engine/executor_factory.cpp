#include "engine/executor_factory.hpp"

#include "engine/config_mapping.hpp"
#include "engine/maneuver_executor.hpp"
#include "engine/mcu_bridge.hpp"
#include "engine/motion_executor.hpp"

namespace feedloop::engine {
namespace {

// A config without MCUs: batches go to an ideal plant that executes every step exactly
// (counted, not simulated).
struct IdealPlant final : stepgen::BatchSink {
  void on_batch(const stepgen::StepBatch& b) override { steps += b.steps; }
  uint64_t steps = 0;
};

}  // namespace

Result<std::unique_ptr<CommandExecutor>> make_executor(const config::MachineConfig& cfg) {
  // Voltage-driven DC motors: output maneuvering on the simulated plant, no steps, no MCUs.
  if (cfg.drive == config::Drive::dc_servo) return make_maneuver_executor(cfg);
  auto stack = make_motion_stack(cfg);
  if (!stack.ok()) return stack.error();
  return std::unique_ptr<CommandExecutor>(std::move(stack.value().executor));
}

MotionOptions motion_options(const config::MachineConfig& cfg) {
  MotionOptions mo;
  mo.lead_s = cfg.stepgen.queue_ahead_ms * 1e-3;
  // The PI on the MCU (control.loop: device): the host's commands and r(t) go out as far ahead as
  // the steps, so a host stall shorter than that changes nothing. On the host: its loop delay.
  const bool device_loop = cfg.control.mode == config::ControlMode::pi && cfg.control.loop == config::ControlLoop::device;
  mo.control_lead_s = device_loop ? cfg.stepgen.queue_ahead_ms * 1e-3 : cfg.control.command_lead_ms * 1e-3;
  // With the sub-step trim the loop can settle within a count; its integral's tail after a stop
  // (an overshoot of up to ~0.2 mm decaying with ~70 ms) needs ~0.7 s for that, not 0.4.
  if (device_loop && cfg.control.sub_step_trim) mo.control_settle_s = 0.8;
  return mo;
}

Result<MotionStack> make_motion_stack(const config::MachineConfig& cfg) {
  return make_motion_stack(cfg, motion_options(cfg));
}

Result<MotionStack> make_motion_stack(const config::MachineConfig& cfg, const MotionOptions& mo,
                                      StepObserver* observer) {
  if (cfg.drive == config::Drive::dc_servo)  // voltage-driven axes: no step pipeline
    return Error{"drive: dc_servo has no step pipeline: build its executor with make_executor()"};
  const planner::PlannerConfig pcfg = planner_config(cfg);
  if (Status s = pcfg.validate(); !s) return s.error();
  StepPipelineParams sp;
  sp.steps_per_mm = steps_per_mm(cfg);
  sp.mcu_clock_hz = static_cast<double>(cfg.stepgen.mcu_clock_hz);
  sp.max_step_error_us = cfg.stepgen.max_step_error_us;
  sp.observer = observer;
  // The control law (sampled path) when the config asks for closed loop or a feedforward filter.
  auto control = make_servo_control(cfg);
  if (!control.ok()) return control.error();
  if (cfg.mcus.empty()) {
    auto ex = std::make_unique<MotionExecutor>(pcfg, sp, std::make_shared<IdealPlant>(), mo);
    if (control.value()) ex->set_control(std::move(control.value()));
    return MotionStack{std::move(ex), nullptr};
  }
  // The MCUs of the config (mock: virtual MCUs driving the plant simulator; serial/usb: sessions
  // on the real links) behind the step pipeline, serviced by the servo thread.
  auto bridge = make_mcu_bridge(cfg);
  if (!bridge.ok()) return bridge.error();
  std::shared_ptr<McuBridge> b = std::move(bridge.value());
  auto ex = std::make_unique<MotionExecutor>(pcfg, sp, b, mo);
  ex->set_backend(b.get());
  if (control.value()) ex->set_control(std::move(control.value()));
  return MotionStack{std::move(ex), std::move(b)};
}

MachineOptions machine_options(const config::MachineConfig& cfg) {
  MachineOptions o;
  o.servo_rate_hz = cfg.servo.rate_hz;
  o.realtime_priority = cfg.servo.realtime_priority;
  o.lock_memory = cfg.servo.lock_memory;
  o.min_extrude_temp_c = cfg.extruder.min_extrude_temp;
  return o;
}

}  // namespace feedloop::engine
