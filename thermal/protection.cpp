#include "thermal/protection.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace feedloop::thermal {

const char* to_string(ThermalRule r) {
  switch (r) {
    case ThermalRule::kNone:
      return "none";
    case ThermalRule::kSensorOpen:
      return "sensor open";
    case ThermalRule::kSensorShort:
      return "sensor short";
    case ThermalRule::kMinTemp:
      return "min temperature";
    case ThermalRule::kMaxTemp:
      return "max temperature";
    case ThermalRule::kHeatingWatch:
      return "heating failed";
    case ThermalRule::kRunaway:
      return "thermal runaway";
    case ThermalRule::kVerifyHeater:
      return "verify_heater";
    case ThermalRule::kStuckSensor:
      return "sensor stuck";
    case ThermalRule::kMcuWatchdog:
      return "mcu heater watchdog";
    case ThermalRule::kMcuMaxTemp:
      return "mcu max temperature";
  }
  return "unknown";
}

const char* describe(const ThermalFault& f, char* buf, unsigned cap) {
  const char* name = to_string(f.rule);
  switch (f.rule) {
    case ThermalRule::kSensorOpen:
    case ThermalRule::kSensorShort:
      std::snprintf(buf, cap, "%s: adc %.4f reads %.1f C", name, f.a, f.temp_c);
      break;
    case ThermalRule::kMinTemp:
      std::snprintf(buf, cap, "%s: %.1f C below min_temp %.1f C", name, f.temp_c, f.a);
      break;
    case ThermalRule::kMaxTemp:
    case ThermalRule::kMcuMaxTemp:
      std::snprintf(buf, cap, "%s: %.1f C above max_temp %.1f C", name, f.temp_c, f.a);
      break;
    case ThermalRule::kHeatingWatch:
      std::snprintf(buf, cap,
                    "%s: %.1f C after %.1f s, needed %.1f C (+%.1f C per %.1f s, target %.1f C)",
                    name, f.temp_c, f.b, f.a, f.c, f.b, f.target_c);
      break;
    case ThermalRule::kRunaway:
      std::snprintf(buf, cap, "%s: %.1f C below target for %.1f s (hysteresis %.1f C)", name, f.a,
                    f.b, f.c);
      break;
    case ThermalRule::kVerifyHeater:
      std::snprintf(buf, cap,
                    "%s: %.1f C*s accumulated below target %.1f C - %.1f C (max_error %.1f)", name,
                    f.a, f.target_c, f.c, f.b);
      break;
    case ThermalRule::kStuckSensor:
      std::snprintf(buf, cap, "%s: adc %.5f unchanged for %.1f s with a target of %.1f C", name, f.a,
                    f.b, f.target_c);
      break;
    case ThermalRule::kMcuWatchdog:
      std::snprintf(buf, cap, "%s: no confirmation from the host for %.1f s, heater off", name,
                    f.a);
      break;
    case ThermalRule::kNone:
      std::snprintf(buf, cap, "none");
      break;
  }
  return buf;
}

void ThermalProtection::reset() {
  *this = ThermalProtection(p_);
}

ThermalFault ThermalProtection::trip(ThermalRule r, double t_s, double temp_c, double target_c,
                                     double a, double b, double c) {
  fault_ = ThermalFault{r, t_s, temp_c, target_c, a, b, c};
  return fault_;
}

ThermalFault ThermalProtection::check(double t_s, double temp_c, double target_c, double adc,
                                      bool /*heater_on*/) {
  if (fault_) return fault_;
  // Sensor and range (checked always, heater on or off: Marlin's min/max temp, Klipper's ADC
  // range).
  if (adc >= p_.open_adc) return trip(ThermalRule::kSensorOpen, t_s, temp_c, target_c, adc, 0, 0);
  if (adc <= p_.short_adc) return trip(ThermalRule::kSensorShort, t_s, temp_c, target_c, adc, 0, 0);
  if (!(temp_c <= p_.max_temp_c))
    return trip(ThermalRule::kMaxTemp, t_s, temp_c, target_c, p_.max_temp_c, 0, 0);
  if (!(temp_c >= p_.min_temp_c))
    return trip(ThermalRule::kMinTemp, t_s, temp_c, target_c, p_.min_temp_c, 0, 0);
  m_.max_temp_c = std::max(m_.max_temp_c, temp_c);
  m_.min_temp_c = std::min(m_.min_temp_c, temp_c);
  const bool on = target_c > 0.0;

  // Stuck sensor.
  // With a target set, the heater on or regulating off: a live sensor never reads the same twice
  // for long. (Off, a frozen reading harms nothing.)
  if (!on || adc != stuck_adc_) {
    stuck_adc_ = adc;
    stuck_since_s_ = t_s;
  }
  m_.max_stuck_s = std::max(m_.max_stuck_s, t_s - stuck_since_s_);
  if (on && p_.stuck_period_s > 0 && t_s - stuck_since_s_ >= p_.stuck_period_s) {
    return trip(ThermalRule::kStuckSensor, t_s, temp_c, target_c, adc, t_s - stuck_since_s_, 0);
  }

  // Marlin: a new (higher) target arms the watch and the runaway state machine.
  if (target_c != last_target_c_) {
    runaway_ = on ? Runaway::kFirstHeating : Runaway::kInactive;
    watching_ = false;
    if (on && p_.watch_period_s > 0 &&
        temp_c < target_c - (p_.watch_increase_c + p_.runaway_hysteresis_c + 1.0)) {
      watching_ = true;
      watch_deadline_s_ = t_s + p_.watch_period_s;
      watch_goal_c_ = temp_c + p_.watch_increase_c;
    }
    last_target_c_ = target_c;
  }
  if (watching_ && t_s >= watch_deadline_s_) {
    m_.min_watch_headroom_c = std::min(m_.min_watch_headroom_c, temp_c - watch_goal_c_);
    if (temp_c < watch_goal_c_)
      return trip(ThermalRule::kHeatingWatch, t_s, temp_c, target_c, watch_goal_c_,
                  p_.watch_period_s, p_.watch_increase_c);
    // Re-arm while still far from the target (Marlin's start_watching_hotend).
    watching_ = temp_c < target_c - (p_.watch_increase_c + p_.runaway_hysteresis_c + 1.0);
    watch_deadline_s_ = t_s + p_.watch_period_s;
    watch_goal_c_ = temp_c + p_.watch_increase_c;
  }
  if (p_.runaway_period_s > 0) {
    switch (runaway_) {
      case Runaway::kInactive:
        break;
      case Runaway::kFirstHeating:
        if (temp_c >= target_c) {
          runaway_ = Runaway::kStable;
          runaway_since_s_ = t_s;
        }
        break;
      case Runaway::kStable:
        m_.max_below_hysteresis_s = std::max(m_.max_below_hysteresis_s, t_s - runaway_since_s_);
        if (temp_c >= target_c - p_.runaway_hysteresis_c) {
          runaway_since_s_ = t_s;
        } else if (t_s - runaway_since_s_ >= p_.runaway_period_s) {
          return trip(ThermalRule::kRunaway, t_s, temp_c, target_c, target_c - temp_c,
                      t_s - runaway_since_s_, p_.runaway_hysteresis_c);
        }
        break;
    }
  }

  // Klipper verify_heater, once a second.
  if (p_.verify_max_error_cs > 0 && t_s >= verify_next_s_) {
    verify_next_s_ = (verify_next_s_ < 0 ? t_s : verify_next_s_) + 1.0;
    if (verify_next_s_ <= t_s) verify_next_s_ = t_s + 1.0;
    const double h = p_.verify_hysteresis_c;
    if (temp_c >= target_c - h || !on) {
      approaching_ = starting_approach_ = false;
      if (temp_c <= target_c + h) verify_error_cs_ = 0.0;
    } else {
      verify_error_cs_ += (target_c - h) - temp_c;
      if (!approaching_) {
        if (target_c != verify_last_target_c_) {
          approaching_ = starting_approach_ = true;
          goal_temp_c_ = temp_c + p_.verify_heating_gain_c;
          goal_time_s_ = t_s + p_.verify_gain_time_s;
        } else if (m_.max_verify_error_cs = std::max(m_.max_verify_error_cs, verify_error_cs_);
                   verify_error_cs_ >= p_.verify_max_error_cs) {
          return trip(ThermalRule::kVerifyHeater, t_s, temp_c, target_c, verify_error_cs_,
                      p_.verify_max_error_cs, h);
        }
      } else if (temp_c >= goal_temp_c_) {
        starting_approach_ = false;
        verify_error_cs_ = 0.0;
        goal_temp_c_ = temp_c + p_.verify_heating_gain_c;
        goal_time_s_ = t_s + p_.verify_gain_time_s;
      } else if (t_s >= goal_time_s_) {
        approaching_ = false;
      } else if (starting_approach_) {
        goal_temp_c_ = std::min(goal_temp_c_, temp_c + p_.verify_heating_gain_c);
      }
    }
    verify_last_target_c_ = target_c;
  }
  return fault_;
}

}  // namespace feedloop::thermal
