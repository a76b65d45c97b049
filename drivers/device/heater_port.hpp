// What a microcontroller drives and reads for a heater: a PWM output and an ADC input on the
// thermistor's divider; and a fan's PWM. The device side (heater_board.hpp) calls it; the thermal
// plant (sim/thermal_plant.hpp) implements it; firmware would implement it with a timer and an ADC.
// Times are true times in seconds, never decreasing between calls.
#pragma once

#include <cstdint>

namespace feedloop::device {

class HeaterPort {
 public:
  virtual ~HeaterPort() = default;
  // PWM duty from t_s on, 0..1.
  virtual void set_duty(double t_s, double duty) = 0;
  // One ADC conversion at t_s, full scale 65535 (the divider's fraction R / (R + R_pullup)).
  virtual uint16_t read_adc(double t_s) = 0;
};

class FanPort {
 public:
  virtual ~FanPort() = default;
  virtual void set_duty(double t_s, double duty) = 0;
};

}  // namespace feedloop::device
