// What a microcontroller drives and reads: one motor's step/dir/enable pins and one encoder.
// The virtual MCU (drivers/device) calls it; the plant simulator (sim/) implements it; a
// firmware port would implement it with GPIO and an SPI/SSI encoder read.
//
// Times are on the simulation's true time line in seconds (the virtual MCU converts its own
// drifting tick clock to true time before calling), and never decrease between calls.
#pragma once

#include <cstdint>

namespace feedloop::device {

class MotorPort {
 public:
  virtual ~MotorPort() = default;
  // One step pulse at t_s; direction +1 or -1 (in joint coordinates: +1 = towards +mm).
  virtual void step(double t_s, int direction) = 0;
  // A step the device decided itself (the device loop's correction, a controlled stop's ramp), not
  // one the host queued. The same pulse on the pins; an observer that checks the host's steps
  // (engine/mcu_bridge.cpp) tells the two apart.
  virtual void device_step(double t_s, int direction) { step(t_s, direction); }
  // Driver enable: a disabled motor holds no torque.
  virtual void set_enabled(double t_s, bool enabled) = 0;
  // The driver's current vector moved by `fraction` of one (micro)step beyond the step count, from
  // t_s on (|fraction| <= 1): the device loop's correction below one step (LoopParams::
  // sub_step_trim). A driver with direct coil-current control does it (Trinamic's XDIRECT mode;
  // the simulated drivers); one without ignores it, and the loop then corrects in whole steps.
  virtual void set_step_fraction(double t_s, float fraction) {
    (void)t_s;
    (void)fraction;
  }
  // Encoder reading at t_s, in counts of the encoder's resolution (signed, carriage side).
  virtual int64_t read_encoder_counts(double t_s) = 0;
  // The endstop input's level at t_s (protocol v3 homing). A motor without an endstop reads 0.
  virtual bool read_endstop(double t_s) {
    (void)t_s;
    return false;
  }
  // The encoder's index line at t_s (its reference mark: high over one count at each mark). An
  // encoder without an index reads 0.
  virtual bool read_encoder_index(double t_s) {
    (void)t_s;
    return false;
  }
};

}  // namespace feedloop::device
