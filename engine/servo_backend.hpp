// What the motion executor's servo cycle talks to besides the step batches: the machine's MCUs
// (real or simulated). Implemented by engine::McuBridge; absent (nullptr) for the ideal plant of
// batch mode. Owner: the servo thread calls service() and tick_map(); fault() and
// fault_message() may be read from any thread.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "drivers/stepgen/step_generator.hpp"
#include "engine/device_loop_telemetry.hpp"
#include "engine/link_telemetry.hpp"
#include "engine/shared_heater_port.hpp"
#include "engine/telemetry_tap.hpp"

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
  // Host time (s) whose carriage position an encoder sample of `joint` taken at `mcu_clock` shows
  // (the clock sync's map inverted, less the encoder's delay; NaN: unknown). Servo thread.
  virtual double encoder_sample_time_s(int /*joint*/, int64_t /*mcu_clock*/) const { return NAN; }
  // The encoder's delay of `joint` (model.gantry.<axis>.encoder_delay_ms), s. Any thread.
  virtual double encoder_delay_s(int /*joint*/) const { return 0.0; }
  // Each MCU link as last seen by the servo thread (at most every 10 ms). Any thread.
  virtual void links(LinkTelemetrySet& out) const { out.count = 0; }

  // The device loop (control.loop: device; engine/device_loop_link.hpp). Servo thread.
  // True when `joint`'s PI runs on its MCU: the motion stage then streams r(t) to it.
  virtual bool device_loop(int /*joint*/) const { return false; }
  // One sample of the desired carriage position r (mm, the encoder's frame: encoder_mm()'s) at
  // `mcu_clock` (ticks of the joint's MCU, through the motion's clock frame: the caller converts
  // with the maps it also gives the steps); samples come in time order, queue_ahead_ms ahead.
  virtual void queue_target(int /*joint*/, int64_t /*mcu_clock*/, double /*r_mm*/) {}
  // Sends the targets pending; `end_of_motion`: the motion ended, r holds at its last sample.
  virtual void flush_targets(bool /*end_of_motion*/) {}
  // Lost-step events the device loops reported (each made up on the device). Any thread.
  virtual unsigned long long device_lost_step_events() const { return 0; }
  // The device loops' events since the last call (lost steps, encoder faults, following errors),
  // with print_time_s holding the host time of the event. Servo thread.
  virtual size_t take_device_events(ServoEvent* /*out*/, size_t /*cap*/) { return 0; }
  // What each joint's device loop reported so far (e, y, correction, tick cost, counters; all
  // disabled without device loops). Any thread.
  virtual void device_loops(DeviceLoopTelemetrySet& out) const { out = DeviceLoopTelemetrySet{}; }
  // The device loops' reports (LOOP_REPORT) since the last call, in arrival order. Servo thread.
  virtual size_t take_device_reports(DeviceLoopReport* /*out*/, size_t /*cap*/) { return 0; }
  // The encoder samples since the last call, each on its MCU's clock, in mm from the encoder's
  // zero (no offset). Servo thread.
  virtual size_t take_encoder_samples(EncoderReading* /*out*/, size_t /*cap*/) { return 0; }

  // Homing through the endstops (docs/homing.md; drivers/host/homing.hpp on each joint's MCU).
  enum class HomingState { kIdle, kRunning, kDone, kFailed };
  // `joint` has an endstop and a homing sequence. Any thread (fixed at construction). On a CoreXY
  // machine the homing's "joints" are the Cartesian axes X, Y, Z (X and Y each move both motors).
  virtual bool can_home(int /*joint*/) const { return false; }
  // Servo thread: switches the drivers of the joints in joint_mask off (M18/M84) or on. The
  // enable is per MCU: every motor of an MCU that drives a joint of the mask. Default: no drivers.
  virtual void set_motors_enabled(unsigned /*joint_mask*/, bool /*on*/) {}
  // Servo thread, with no motion running: starts homing every joint in joint_mask (bit j) at host
  // time now_s, the joints together. false (and the reason in why) when it cannot start.
  virtual bool start_homing(unsigned /*joint_mask*/, double /*now_s*/, char* why, size_t cap) {
    if (cap > 0) why[0] = '\0';
    return false;
  }
  // Servo thread: stops a running homing (cancel, emergency stop); it ends kFailed.
  virtual void abort_homing(const char* /*why*/) {}
  // Servo thread: the homing's progress (service() advances it).
  virtual HomingState homing_state() const { return HomingState::kIdle; }
  // After kDone: each homed joint's motor position (mm) where it stopped. Servo thread.
  virtual double homed_position_mm(int /*joint*/) const { return NAN; }
  // After kDone: how far the homing moved an axis it did not home (mm; CoreXY: homing X moves Y
  // by half the second motor's relayed overshoot). 0 where the axes are the joints.
  virtual double homing_shift_mm(int /*axis*/) const { return 0.0; }
  // After kDone or kFailed: the MCU clock of the last step the homing queued on `joint`'s MCU
  // (INT64_MIN: none); the step stream continues after it. Servo thread.
  virtual int64_t homing_last_step_clock(int /*joint*/) const { return INT64_MIN; }
  // After kFailed: why (Klipper's wording where it has one). Servo thread.
  virtual void homing_error(char* out, size_t cap) const {
    if (cap > 0) out[0] = '\0';
  }
  // The endstop of `joint` as last queried (M119): -1 none or unknown, 0 open, 1 triggered; and
  // whether it sits at the max end. Any thread.
  virtual int endstop_state(int /*joint*/) const { return -1; }
  virtual bool endstop_at_max(int /*joint*/) const { return false; }

  // Heaters on the motion MCUs' own links (engine/shared_heater_port.hpp): one port per motion
  // MCU that drives heaters or fans, for make_thermal_loop. nullptr: none. Fixed at construction.
  virtual const SharedHeaterPorts* heater_ports() const { return nullptr; }
};

}  // namespace feedloop::engine
