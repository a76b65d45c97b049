// An endstop switch for the plant simulator: a mechanical (or optical) switch at a configured
// position whose trip point scatters from one press to the next (Gaussian repeatability sigma,
// redrawn every time the switch releases) and which releases only hysteresis_mm past its trip point
// (the contact's travel differential). Which effects a real switch has and their sizes: Omron
// D2F-class microswitches quote a few um of repeatability and tens of um of differential travel;
// Klipper's endstop phase docs (Endstop_Phase.md) put typical switch noise at several um.
// The host's homing model knows only position_endstop: the scatter and the hysteresis are effects
// it lacks.
//
// EndstopAxis wraps a GantryAxis (the carriage's true position) and a switch into one
// device::MotorPort, so the virtual MCU reads the switch on the carriage it steps.
// Owner: the simulation thread. RT-safe (no allocation).
#pragma once

#include <cstdint>

#include "core/result.hpp"
#include "core/rng.hpp"
#include "drivers/device/motor_port.hpp"
#include "sim/gantry_axis.hpp"

namespace feedloop::sim {

struct EndstopSwitchParams {
  double position_mm = 0.0;     // mean trip point (carriage position)
  bool at_min = true;           // pressed when the carriage is at or below the trip point (a max
                                // endstop: at or above)
  double sigma_mm = 0.002;      // trip point repeatability (1 sigma)
  double hysteresis_mm = 0.05;  // released only this far back past the trip point
  uint64_t seed = 7;
};

class EndstopSwitch {
 public:
  static Result<EndstopSwitch> create(const EndstopSwitchParams& p);
  // The switch's state with the carriage at carriage_mm (call in time order).
  bool sample(double carriage_mm);
  bool pressed() const { return pressed_; }
  double trip_mm() const { return trip_mm_; }  // the current press's trip point (ground truth)
  uint64_t presses() const { return presses_; }
  const EndstopSwitchParams& params() const { return p_; }

 private:
  explicit EndstopSwitch(const EndstopSwitchParams& p);
  void draw_trip();
  EndstopSwitchParams p_;
  Rng rng_;
  double trip_mm_ = 0.0;
  bool pressed_ = false;
  uint64_t presses_ = 0;
};

class EndstopAxis final : public device::MotorPort {
 public:
  EndstopAxis(GantryAxis& axis, EndstopSwitch& sw) : axis_(&axis), sw_(&sw) {}
  void step(double t_s, int direction) override { axis_->step(t_s, direction); }
  void set_enabled(double t_s, bool enabled) override { axis_->set_enabled(t_s, enabled); }
  void set_step_fraction(double t_s, float f) override { axis_->set_step_fraction(t_s, f); }
  int64_t read_encoder_counts(double t_s) override { return axis_->read_encoder_counts(t_s); }
  bool read_encoder_index(double t_s) override { return axis_->read_encoder_index(t_s); }
  bool read_endstop(double t_s) override {
    axis_->advance_to(t_s);
    return sw_->sample(axis_->carriage_mm());
  }

 private:
  GantryAxis* axis_;
  EndstopSwitch* sw_;
};

}  // namespace feedloop::sim
