// Heaters and fans on a motion MCU's own link (one board for both, the usual printer): the motion
// MCU's McuSession belongs to the servo thread (McuBridge); the thermal loop runs on the thermal
// thread (McuHeaterLink). A SharedHeaterPort carries the heater messages between the two without a
// lock: the thermal thread's CONFIGURE_HEATER / SET_HEATER / SET_FAN wait in one ring until the
// servo thread queues them on the session; the MCU's HEATER_REPORT / HEATER_FAULT come back in the
// other, each with the clock map in use when it arrived (the session's clock sync, in host time).
//   ThermalLoop --> McuHeaterLink --to_mcu--> [servo thread] McuBridge --> McuSession --> MCU
//   ThermalLoop <-- McuHeaterLink <-from_mcu-- [servo thread] McuBridge <-- McuSession <-- MCU
// The bridge publishes the link's state (identified, protocol version, clock rate, the last frame
// from the MCU) and, when the motion side faults, the fault: every MCU was stopped, and a stopped
// MCU turns its heaters off (Klipper's rule: a shutdown of any MCU shuts the printer down).
// Real time (the servo side): fixed rings, atomics and a seqlock; nothing allocates or waits.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "core/seqlock.hpp"
#include "core/spsc_queue.hpp"

namespace feedloop::engine {

class SharedHeaterPort {
 public:
  static constexpr size_t kRing = 64;  // messages each way (a heater sends one per 0.3 s)

  struct Message {
    uint8_t n = 0;
    uint8_t bytes[32] = {};
    // from_mcu only: MCU ticks -> host seconds, s = (ticks - offset_ticks) / ticks_per_s, when
    // clock_ready; else the host time the bridge took the message from the session.
    bool clock_ready = false;
    double offset_ticks = 0.0, ticks_per_s = 1.0;
    double arrival_s = 0.0;
  };

  explicit SharedHeaterPort(std::string mcu_name)
      : mcu_name_(std::move(mcu_name)), to_mcu_(kRing), from_mcu_(kRing) {}
  SharedHeaterPort(const SharedHeaterPort&) = delete;
  SharedHeaterPort& operator=(const SharedHeaterPort&) = delete;

  const std::string& mcu_name() const { return mcu_name_; }

  // ---- thermal thread ----
  // False when the ring is full (the servo thread is not taking them: the link reports it).
  bool send_to_mcu(const uint8_t* msg, size_t n) {
    Message m;
    m.n = static_cast<uint8_t>(std::min(n, sizeof m.bytes));
    std::memcpy(m.bytes, msg, m.n);
    return to_mcu_.try_push(m);
  }
  bool take_from_mcu(Message& out) { return from_mcu_.try_pop(out); }

  // ---- servo thread (RT-safe) ----
  bool take_to_mcu(Message& out) { return to_mcu_.try_pop(out); }
  // False when full: the report is dropped and counted (the thermal loop's report timeout notices
  // a thread that stopped reading).
  bool deliver_from_mcu(const Message& m) {
    if (from_mcu_.try_push(m)) return true;
    dropped_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  // The session's state, published every servo period.
  void publish(bool ready, uint16_t version, uint32_t clock_hz, double last_heard_s) {
    clock_hz_.store(clock_hz, std::memory_order_relaxed);
    version_.store(version, std::memory_order_relaxed);
    last_heard_s_.store(last_heard_s, std::memory_order_relaxed);
    ready_.store(ready, std::memory_order_release);
  }
  // The MCU was stopped (a fault of the motion side): the first message is kept.
  void fail(const char* why) {
    if (failed_.load(std::memory_order_acquire)) return;
    Text t;
    std::snprintf(t.text, sizeof t.text, "%s", why);
    fault_.store(t);
    failed_.store(true, std::memory_order_release);
  }

  // ---- any thread ----
  bool ready() const { return ready_.load(std::memory_order_acquire); }
  uint16_t version() const { return version_.load(std::memory_order_relaxed); }
  uint32_t clock_hz() const { return clock_hz_.load(std::memory_order_relaxed); }
  double last_heard_s() const { return last_heard_s_.load(std::memory_order_relaxed); }
  bool failed() const { return failed_.load(std::memory_order_acquire); }
  std::string fault() const { return failed() ? std::string(fault_.load().text) : std::string(); }
  uint64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }

 private:
  struct Text {
    char text[200] = {};
  };
  std::string mcu_name_;
  SpscQueue<Message> to_mcu_, from_mcu_;
  std::atomic<bool> ready_{false}, failed_{false};
  std::atomic<uint16_t> version_{0};
  std::atomic<uint32_t> clock_hz_{0};
  std::atomic<double> last_heard_s_{-1e300};
  std::atomic<uint64_t> dropped_{0};
  Seqlock<Text> fault_;
};

// The motion MCUs that drive heaters or fans, one port each (McuBridge::heater_ports()).
using SharedHeaterPorts = std::vector<std::shared_ptr<SharedHeaterPort>>;

}  // namespace feedloop::engine
