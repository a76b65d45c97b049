// Thermal protection of one heater: the rules of Marlin (Marlin/src/module/temperature.cpp,
// Configuration_adv.h THERMAL_PROTECTION_*) and Klipper (klippy/extras/verify_heater.py), checked
// on every temperature sample. A fault names the rule and its numbers; the caller turns every
// heater off and stops the print. Pure; no allocation.
//
//  - min/max temperature (both): a reading outside [min_temp_c, max_temp_c]; the ADC fraction
//    tells an open sensor (adc ~ 1) or a short (adc ~ 0) from a real over/under temperature.
//  - heating watch (Marlin WATCH_TEMP_PERIOD / WATCH_TEMP_INCREASE, 20 s / +2 C): after the target
//    rises, the temperature must gain watch_increase_c within watch_period_s, re-armed each time it
//    does, until it is within watch_increase_c + hysteresis_c of the target.
//  - runaway (Marlin THERMAL_PROTECTION_PERIOD / HYSTERESIS, 40 s / 4 C): once the target was
//    reached, the temperature may stay more than hysteresis_c below it for runaway_period_s at
//    most.
//  - Klipper's verify_heater (max_error 120, check_gain_time 20 s, hysteresis 5 C, heating_gain
//    2 C), evaluated once a second: the integrated shortfall below target - hysteresis may not
//    exceed max_error C*s unless the heater is still approaching (gaining heating_gain within
//    check_gain_time).
//  - stuck sensor (feedloop's own rule; neither firmware has it): with a target set, the reported
//    ADC value (the mean of the report's samples) did not change at all for stuck_period_s. A real
//    ADC always shows some noise; a quiet one needs a longer stuck_period_s (0 disables the rule).
#pragma once

#include <cstdint>

namespace feedloop::thermal {

struct ProtectionParams {
  double min_temp_c = 0.0;
  double max_temp_c = 300.0;
  double open_adc = 0.995;   // adc at or above: "sensor open"
  double short_adc = 0.005;  // adc at or below: "sensor short"
  // Marlin (0 disables a rule)
  double watch_period_s = 20.0;
  double watch_increase_c = 2.0;
  double runaway_period_s = 40.0;
  double runaway_hysteresis_c = 4.0;
  // Klipper verify_heater (max_error 0 disables)
  double verify_max_error_cs = 120.0;
  double verify_gain_time_s = 20.0;
  double verify_hysteresis_c = 5.0;
  double verify_heating_gain_c = 2.0;
  double stuck_period_s = 10.0;
};

enum class ThermalRule : uint8_t {
  kNone,
  kSensorOpen,
  kSensorShort,
  kMinTemp,
  kMaxTemp,
  kHeatingWatch,
  kRunaway,
  kVerifyHeater,
  kStuckSensor,
  kMcuWatchdog,
  kMcuMaxTemp,
};
const char* to_string(ThermalRule r);

struct ThermalFault {
  ThermalRule rule = ThermalRule::kNone;
  double t_s = 0.0;
  double temp_c = 0.0, target_c = 0.0;
  double a = 0.0, b = 0.0, c = 0.0;  // the rule's numbers (see describe())
  explicit operator bool() const { return rule != ThermalRule::kNone; }
};
// "thermal runaway: 4.6 C below target for 40.0 s (hysteresis 4.0 C)" etc.
// Writes at most cap bytes (NUL-terminated); returns buf.
const char* describe(const ThermalFault& f, char* buf, unsigned cap);

// How close a heater came to each rule (for the benchmark of the margins, bench/thermal): the
// smallest gain over target at a watch deadline (C above the goal), the longest time below the
// runaway hysteresis, the largest verify_heater error, the longest unchanged ADC, the hottest and
// coldest reading.
struct ProtectionMargins {
  double min_watch_headroom_c = 1e9;
  double max_below_hysteresis_s = 0.0;
  double max_verify_error_cs = 0.0;
  double max_stuck_s = 0.0;
  double max_temp_c = -1e9, min_temp_c = 1e9;
};

class ThermalProtection {
 public:
  explicit ThermalProtection(const ProtectionParams& p = {}) : p_(p) {}
  // One sample: time, temperature, target (<= 0: off), the raw ADC value (as sampled, 0..1) and
  // whether the heater was driven (power > 0). Returns the first fault (latched) or none.
  ThermalFault check(double t_s, double temp_c, double target_c, double adc, bool heater_on);
  const ThermalFault& fault() const { return fault_; }
  const ProtectionMargins& margins() const { return m_; }
  void reset();  // clears a latched fault (M999 / a new print)
  const ProtectionParams& params() const { return p_; }

 private:
  ThermalFault trip(ThermalRule r, double t_s, double temp_c, double target_c, double a, double b,
                    double c);
  ProtectionParams p_;
  ThermalFault fault_;
  ProtectionMargins m_;
  double last_target_c_ = 0.0;
  // Marlin watch
  bool watching_ = false;
  double watch_deadline_s_ = 0.0, watch_goal_c_ = 0.0;
  // Marlin runaway
  enum class Runaway : uint8_t { kInactive, kFirstHeating, kStable } runaway_ = Runaway::kInactive;
  double runaway_since_s_ = 0.0;  // last time the temperature was within the hysteresis
  // Klipper verify_heater
  double verify_next_s_ = -1.0;
  double verify_last_target_c_ = 0.0, verify_error_cs_ = 0.0, goal_temp_c_ = 0.0,
         goal_time_s_ = 0.0;
  bool approaching_ = false, starting_approach_ = false;
  // stuck sensor
  double stuck_adc_ = -1.0, stuck_since_s_ = 0.0;
};

}  // namespace feedloop::thermal
