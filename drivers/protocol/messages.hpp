// Message types of the feedloop MCU protocol (docs/protocol.md, "Messages"). Every payload of a
// data frame is one message: a type byte followed by its fields (varints, zigzag varints for
// signed values). Encoding/decoding is header-only and allocation-free: the device uses it.
#pragma once

#include <cstddef>
#include <cstdint>

#include "drivers/protocol/frame.hpp"
#include "drivers/protocol/varint.hpp"

namespace feedloop::protocol {

// The newest version this code speaks, and the oldest it still accepts (docs/protocol.md,
// "Versioning"): a device answers IDENTIFY with the version both speak (the host's, when it is in
// [kMinProtocolVersion, kProtocolVersion]), so a v1 host still works with a v2 device.
// Version 2 adds the device loop's messages (CONFIGURE_LOOP, QUEUE_TARGET, LOOP_REPORT,
// LOOP_EVENT). Version 3 adds heaters, fans and endstops; version 4 the encoder count at an
// endstop's trigger (ENDSTOP_HOME's flags byte, ENDSTOP_TRIGGER's trailing count).
inline constexpr uint16_t kProtocolVersion = 4;
inline constexpr uint16_t kMinProtocolVersion = 1;

enum class MsgType : uint8_t {
  // host -> device
  kIdentify = 0x01,      // u16 version
  kConfigure = 0x02,     // encoder_period_ticks, samples_per_report, watchdog_ticks
  kQueueSteps = 0x03,    // u8 axis, run_codec body (first_clock, runs)
  kClockQuery = 0x04,    // token
  kEnable = 0x05,        // u8 on
  kEmergencyStop = 0x06, // -
  kHeartbeat = 0x07,     // -
  kStatusQuery = 0x08,   // -
  kConfigureLoop = 0x09, // v2: u8 axis, activation_clock, loop parameters (loop_messages.hpp)
  kQueueTarget = 0x0A,   // v2: u8 axis, n, first clock, zz first pos_nm, n-1 x (dclock, zz dpos_nm)
  kConfigureHeater = 0x0B,  // v3 heaters (heater_messages.hpp): u8 heater, sample/report/limits/watchdog
  kSetHeater = 0x0C,        // v3: u8 heater, u16 duty (0..65535): also the host's re-confirmation
  kSetFan = 0x0D,           // v3: u8 fan, u16 duty
  // v3 endstops (endstop_messages.hpp; ids 0x10-0x14 host->device, 0x90-0x94 device->host)
  kEndstopHome = 0x10,   // v3: u8 axis, u8 trigger_level, var sample_ticks (0: disarm), u8 sample_count
  kEndstopQuery = 0x11,  // v3: u8 axis
  // device -> host
  kIdentifyResponse = 0x81,  // u16 version, clock_hz, u8 axis, u8 name_len, name
  kClockResponse = 0x84,     // token, clock
  kStatus = 0x87,            // clock, steps_executed, zz position, queued_runs, step_hash, u8 flags
  kEncoderReport = 0x88,     // first_clock, period_ticks, n, zz counts[0], zz deltas...
  kErrorReport = 0x89,       // u8 code, clock, zz detail
  kLoopReport = 0x8A,        // v2: u8 axis, telemetry of the device loop (loop_messages.hpp)
  kLoopEvent = 0x8B,         // v2: u8 axis, u8 kind, clock, zz a, zz b
  kHeaterReport = 0x8C,      // v3: u8 heater, clock, u16 adc (0..65535), u16 duty applied
  kHeaterFault = 0x8D,       // v3: u8 heater, u8 reason, clock, u16 adc
  kEndstopTrigger = 0x90,    // v3: u8 axis, trigger_clock, zz trigger_steps, stop_clock, zz stop_steps
  kEndstopState = 0x91,      // v3: u8 axis, u8 pin, u8 armed, u8 triggered
};

// True for the types a device sends (a host refuses any other type from a device).
constexpr bool is_device_to_host(MsgType t) {
  switch (t) {
    case MsgType::kIdentifyResponse:
    case MsgType::kClockResponse:
    case MsgType::kStatus:
    case MsgType::kEncoderReport:
    case MsgType::kErrorReport:
    case MsgType::kLoopReport:
    case MsgType::kLoopEvent:
    case MsgType::kHeaterReport:
    case MsgType::kHeaterFault:
    case MsgType::kEndstopTrigger:
    case MsgType::kEndstopState:
      return true;
    default:
      return false;
  }
}

enum class McuError : uint8_t {
  kNone = 0,
  kVersionMismatch = 1,  // detail: the device's version
  kQueueUnderrun = 2,    // a step time already in the past; detail: ticks late
  kWatchdog = 3,         // no message from the host within watchdog_ticks while enabled
  kQueueOverflow = 4,    // step queue full; detail: runs dropped
  kBadMessage = 5,       // detail: message type
  kEmergencyStop = 6,
  kNotIdentified = 7,    // a command before a successful identify; detail: message type
  kBatchOverlap = 8,     // a batch starts before the previous one ended; detail: ticks
  // v2 (the device loop); each ends a controlled stop (the axes decelerated to rest first).
  kFollowingError = 9,   // |r - y| beyond the limit; detail: axis
  kEncoderFault = 10,    // implausible encoder samples in a row; detail: axis
  kTargetUnderrun = 11,  // r(t)'s queue ended while the axis moved; detail: axis
  kBadLoopConfig = 12,   // CONFIGURE_LOOP refused; detail: device::LoopParamError
  kTargetOverflow = 13,  // QUEUE_TARGET did not fit or its clocks did not increase; detail: axis
};

const char* mcu_error_name(McuError e);

// Status flags.
inline constexpr uint8_t kStatusEnabled = 0x01;
inline constexpr uint8_t kStatusStopped = 0x02;  // shut down after an error until re-identified

// Bounded writer over a caller buffer; ok() false once anything did not fit.
class MsgWriter {
 public:
  MsgWriter(uint8_t* buf, size_t cap) : buf_(buf), cap_(cap) {}
  MsgWriter& u8(uint8_t v) {
    if (pos_ < cap_) buf_[pos_++] = v; else ok_ = false;
    return *this;
  }
  MsgWriter& u16(uint16_t v) { return u8(v & 0xFF).u8(v >> 8); }
  MsgWriter& var(uint64_t v) {
    const size_t p = put_varint(buf_, pos_, cap_, v);
    if (p == 0) ok_ = false; else pos_ = p;
    return *this;
  }
  MsgWriter& zz(int64_t v) { return var(zigzag(v)); }
  MsgWriter& f32(float v) {  // IEEE 754 binary32, little-endian
    uint32_t u = 0;
    __builtin_memcpy(&u, &v, 4);
    return u8(u & 0xFF).u8((u >> 8) & 0xFF).u8((u >> 16) & 0xFF).u8(u >> 24);
  }
  MsgWriter& bytes(const uint8_t* d, size_t n) {
    for (size_t i = 0; i < n; ++i) u8(d[i]);
    return *this;
  }
  bool ok() const { return ok_; }
  size_t size() const { return pos_; }

 private:
  uint8_t* buf_;
  size_t cap_, pos_ = 0;
  bool ok_ = true;
};

class MsgReader {
 public:
  MsgReader(const uint8_t* buf, size_t len) : buf_(buf), len_(len) {}
  uint8_t u8() {
    if (pos_ < len_) return buf_[pos_++];
    ok_ = false;
    return 0;
  }
  uint16_t u16() {
    const uint16_t lo = u8();
    return static_cast<uint16_t>(lo | (u8() << 8));
  }
  uint64_t var() {
    uint64_t v = 0;
    if (!get_varint(buf_, len_, pos_, v)) ok_ = false;
    return v;
  }
  int64_t zz() { return unzigzag(var()); }
  float f32() {
    uint32_t u = u8();
    u |= static_cast<uint32_t>(u8()) << 8;
    u |= static_cast<uint32_t>(u8()) << 16;
    u |= static_cast<uint32_t>(u8()) << 24;
    float v = 0.0f;
    __builtin_memcpy(&v, &u, 4);
    return v;
  }
  const uint8_t* rest(size_t& n) {
    n = len_ - pos_;
    return buf_ + pos_;
  }
  const uint8_t* take(size_t n) {
    if (pos_ + n > len_) {
      ok_ = false;
      return buf_ + len_;
    }
    const uint8_t* p = buf_ + pos_;
    pos_ += n;
    return p;
  }
  bool ok() const { return ok_; }
  bool at_end() const { return pos_ == len_; }

 private:
  const uint8_t* buf_;
  size_t len_, pos_ = 0;
  bool ok_ = true;
};

}  // namespace feedloop::protocol
