// The simulated machine behind the mock transport (DESIGN.md "Data flow": mock -> virtual MCUs +
// plant): the motors the virtual MCUs drive and the ground truth the simulated runs record. The
// MCU bridge (engine/mcu_bridge.hpp) and the simulated runs (engine/sim_run.hpp) see only this
// interface; make_simulated_printer (engine/simulated_printer.hpp) builds it from the config and
// is the one place in engine/ that knows the plant simulator (sim/).
// Owner: the servo thread (like the bridge that holds it). Times are the simulation's time line.
#pragma once

#include <array>
#include <cstdint>

#include "drivers/device/motor_port.hpp"

namespace feedloop::engine {

class SimulatedPlant {
 public:
  virtual ~SimulatedPlant() = default;

  // The motor of joint `joint` (0-2: x y z, or the delta's carriages A B C); nullptr when the
  // joint has no plant model (the extruder: the bridge gives it an ideal motor).
  virtual device::MotorPort* motor(int joint) = 0;
  // The encoder resolution of that joint's plant (mm per count); 0 without a plant model.
  virtual double encoder_mm_per_count(int joint) const = 0;
  // Integrates every plant to t_s with no event. RT-safe.
  virtual void advance_to(double t_s) = 0;

  // Ground truth, for the simulated runs, tests and benchmarks.
  // Carriage (joint) position in machine coordinates, mm; NaN without a plant model.
  virtual double carriage_mm(int joint) const = 0;
  // The nozzle, mm (Cartesian machines: the carriages x, y, z); NaN where unknown.
  virtual std::array<double, 3> nozzle_mm() const = 0;
  // Full steps the joint's motor has lost so far (0 where the plant does not model slips).
  virtual int64_t lost_full_steps(int joint) const = 0;

  // A plant that can fail (an external plant process that exited, answered garbage or went
  // silent): the message, nullptr while healthy. The bridge stops the machine for good on it.
  virtual const char* fault() const { return nullptr; }
  // Slips of the joint's motor so far, in either direction (each 4 full steps); 0 where the plant
  // does not model slips. A slip forward and one back cancel in lost_full_steps, not here.
  virtual int64_t slip_events(int /*joint*/) const { return 0; }
  // Whether the joint's driver is enabled (holding torque); true where the plant does not say.
  virtual bool motor_enabled(int /*joint*/) const { return true; }
};

}  // namespace feedloop::engine
