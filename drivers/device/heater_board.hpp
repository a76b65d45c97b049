// The device side of heaters and fans (protocol v3, drivers/protocol/heater_messages.hpp): fixed
// memory, no heap, no exceptions. Per heater it samples the ADC every sample_period_ticks, reports
// the mean of samples_per_report samples, applies the host's duty, and turns the heater off by
// itself (and reports HEATER_FAULT, latched until reconfigured) when
//  - a sample lies outside [adc_min, adc_max] (its own max/min temperature limit, as Klipper's
//    analog-in range check on the MCU), or
//  - the host has not re-confirmed the duty (SET_HEATER) within confirm_timeout_ticks while the
//    heater is on (Klipper's MAX_HEAT_TIME, 3 s: the host sends the PWM with every reading).
// Driven by its owner's clock: on_message() with the host's messages, run(clock) for what is due;
// pop_message() hands out the reports. Owner: one thread.
#pragma once

#include <cstddef>
#include <cstdint>

#include "drivers/device/heater_port.hpp"
#include "drivers/protocol/heater_messages.hpp"

namespace feedloop::device {

class HeaterBoard {
 public:
  static constexpr int kMaxHeaters = 4;
  static constexpr int kMaxFans = 4;
  static constexpr int kMaxOut = 32;
  static constexpr size_t kMsgCap = 24;

  // ports may be nullptr beyond num; clock_hz converts ticks to the ports' true time.
  HeaterBoard(HeaterPort* const* heaters, int num_heaters, FanPort* const* fans, int num_fans,
              double clock_hz);

  // A host message (type 0x0B-0x0D); false when it is not one of them or malformed.
  bool on_message(const uint8_t* p, size_t n, int64_t now_clock);
  // Samples, limits and watchdogs due up to now_clock.
  void run(int64_t now_clock);
  // Next report or fault, oldest first; false when none. out must hold kMsgCap bytes.
  bool pop_message(uint8_t* out, size_t& n);
  // Every heater off (emergency stop, host lost).
  void all_off(int64_t now_clock);
  // Clock of the next sample due (a large value when nothing is configured).
  int64_t next_event_clock() const;

  struct HeaterState {
    bool configured = false;
    bool faulted = false;
    protocol::HeaterFaultReason fault = protocol::HeaterFaultReason::kNone;
    uint16_t duty = 0;  // applied
    int64_t last_confirm_clock = 0;
    uint16_t last_adc = 0;
  };
  const HeaterState& heater(int i) const { return h_[i].st; }
  uint64_t messages_dropped() const { return dropped_; }

 private:
  struct Heater {
    HeaterPort* port = nullptr;
    protocol::ConfigureHeaterMsg cfg;
    HeaterState st;
    int64_t next_sample_clock = 0;
    uint32_t sum = 0;
    uint16_t nsum = 0;
  };
  void apply(int i, uint16_t duty, int64_t clock);
  void trip(int i, protocol::HeaterFaultReason why, int64_t clock, uint16_t adc);
  void push(const uint8_t* p, size_t n);
  double t_of(int64_t clock) const { return static_cast<double>(clock) / clock_hz_; }

  Heater h_[kMaxHeaters];
  int nh_ = 0;
  FanPort* fans_[kMaxFans] = {};
  int nf_ = 0;
  double clock_hz_;
  uint8_t out_[kMaxOut][kMsgCap] = {};
  size_t out_len_[kMaxOut] = {};
  int out_head_ = 0, out_count_ = 0;
  uint64_t dropped_ = 0;
};

}  // namespace feedloop::device
