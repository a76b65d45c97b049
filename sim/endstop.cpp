// Endstop switch model: see endstop.hpp.
#include "sim/endstop.hpp"

#include <cmath>  // isfinite

namespace feedloop::sim {

Result<EndstopSwitch> EndstopSwitch::create(const EndstopSwitchParams& p) {
  if (!std::isfinite(p.position_mm)) return Error{"endstop position_mm must be finite", {}};
  if (!(p.sigma_mm >= 0.0) || !std::isfinite(p.sigma_mm))
    return Error{"endstop sigma_mm must be >= 0", {}};
  if (!(p.hysteresis_mm >= 0.0) || !std::isfinite(p.hysteresis_mm))
    return Error{"endstop hysteresis_mm must be >= 0", {}};
  return EndstopSwitch(p);
}

EndstopSwitch::EndstopSwitch(const EndstopSwitchParams& p) : p_(p), rng_(p.seed) {
  draw_trip();
}

void EndstopSwitch::draw_trip() {
  trip_mm_ = p_.position_mm + p_.sigma_mm * rng_.gaussian();
}

bool EndstopSwitch::sample(double carriage_mm) {
  // d > 0: the carriage is past the trip point towards the switch.
  const double d = p_.at_min ? trip_mm_ - carriage_mm : carriage_mm - trip_mm_;
  if (!pressed_ && d >= 0.0) {
    pressed_ = true;
    ++presses_;
  } else if (pressed_ && d < -p_.hysteresis_mm) {
    pressed_ = false;
    draw_trip();  // the next press trips elsewhere
  }
  return pressed_;
}

}  // namespace feedloop::sim
