// What the motion executor's servo cycle talks to besides the step batches: the machine's MCUs
// (real or simulated). Implemented by engine::McuBridge; absent (nullptr) for the ideal plant of
// batch mode. Owner: the servo thread calls service() and tick_map(); fault() and
// fault_message() may be read from any thread.
#pragma once

#include <cmath>
#include <cstddef>

#include "drivers/stepgen/step_generator.hpp"
#include "engine/link_telemetry.hpp"

namespace feedloop::engine {

class ServoBackend {
 public:
  virtual ~ServoBackend() = default;
  // Servo thread, at the start of every cycle: transport I/O, clock sync, encoder reports, and
  // (simulation) the virtual MCUs and plants advanced to host time now_s.
  virtual void service(double now_s) = 0;
  // Motion may start: every MCU identified and its clock estimate settled, no fault.
  virtual bool ready() const = 0;
  // Host time (s) -> ticks of the MCU that drives `joint` (the clock sync's estimate).
  virtual stepgen::TickMap tick_map(int joint) const = 0;
  // A fault stopped the machine (an MCU disconnected or stopped); any thread.
  virtual bool fault() const = 0;
  // The fault, naming the MCU (empty when none). Any thread; copies into out (NUL-terminated).
  virtual void fault_message(char* out, size_t cap) const = 0;
  // Latest encoder position of a joint (mm from power-on; NaN when the joint has no encoder or
  // no report arrived yet) and the number of encoder samples received. Any thread.
  virtual double encoder_mm(int joint) const = 0;
  virtual unsigned long long encoder_samples() const = 0;
  // Encoder reports that updated `joint` so far (a new value arrived when it changes). Any thread.
  virtual unsigned long long encoder_reports(int /*joint*/) const { return encoder_samples(); }
  // Host time (s) at which the latest encoder reading of `joint` was sampled (NaN: unknown).
  virtual double encoder_time_s(int /*joint*/) const { return NAN; }
  // Each MCU link as last seen by the servo thread (at most every 10 ms). Any thread.
  virtual void links(LinkTelemetrySet& out) const { out.count = 0; }
};

}  // namespace feedloop::engine
