// Protocol v3: heaters and fans (docs/protocol.md, "Protocol v3: heaters and fans"). Klipper's
// split: the MCU samples the ADC, drives the PWM, turns its heater off by itself on an ADC
// reading outside [adc_min, adc_max] (its own max/min temperature) and when the host has not
// re-confirmed the duty within confirm_timeout_ticks (Klipper's MAX_HEAT_TIME, 3 s); the host runs
// the PID and the thermal protection. Encoders/decoders for both sides, allocation-free; encode_*
// return the size (0 when it does not fit), decode_* take the whole payload and reject a wrong
// type, truncation or trailing bytes.
#pragma once

#include <cstddef>
#include <cstdint>

#include "drivers/protocol/messages.hpp"

namespace feedloop::protocol {

struct ConfigureHeaterMsg {
  uint8_t heater = 0;
  uint32_t sample_period_ticks = 0;       // ADC sampling period
  uint16_t samples_per_report = 1;        // reports carry the mean of this many samples
  uint16_t adc_min = 0, adc_max = 65535;  // outside: the MCU's own limit trips (heater off)
  uint32_t confirm_timeout_ticks = 0;     // no SET_HEATER within this: heater off, fault (0: never)
  uint16_t max_duty = 65535;
};

struct SetHeaterMsg {
  uint8_t heater = 0;
  uint16_t duty = 0;
};

struct SetFanMsg {
  uint8_t fan = 0;
  uint16_t duty = 0;
};

struct HeaterReportMsg {
  uint8_t heater = 0;
  int64_t clock = 0;
  uint16_t adc = 0;   // mean of the report's samples, full scale 65535
  uint16_t duty = 0;  // duty applied at the last sample
};

enum class HeaterFaultReason : uint8_t { kNone = 0, kWatchdog = 1, kAdcRange = 2, kBadConfig = 3 };

struct HeaterFaultMsg {
  uint8_t heater = 0;
  HeaterFaultReason reason = HeaterFaultReason::kNone;
  int64_t clock = 0;
  uint16_t adc = 0;
};

size_t encode_configure_heater(const ConfigureHeaterMsg& m, uint8_t* buf, size_t cap);
bool decode_configure_heater(const uint8_t* p, size_t n, ConfigureHeaterMsg& out);
size_t encode_set_heater(const SetHeaterMsg& m, uint8_t* buf, size_t cap);
bool decode_set_heater(const uint8_t* p, size_t n, SetHeaterMsg& out);
size_t encode_set_fan(const SetFanMsg& m, uint8_t* buf, size_t cap);
bool decode_set_fan(const uint8_t* p, size_t n, SetFanMsg& out);
size_t encode_heater_report(const HeaterReportMsg& m, uint8_t* buf, size_t cap);
bool decode_heater_report(const uint8_t* p, size_t n, HeaterReportMsg& out);
size_t encode_heater_fault(const HeaterFaultMsg& m, uint8_t* buf, size_t cap);
bool decode_heater_fault(const uint8_t* p, size_t n, HeaterFaultMsg& out);

}  // namespace feedloop::protocol
