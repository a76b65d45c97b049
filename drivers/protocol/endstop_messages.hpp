// Protocol v3: endstop messages (docs/protocol.md, "Protocol v3: endstops"). Header-only,
// allocation-free encoders/decoders for both sides. The trigger is handled on the MCU, as in
// Klipper's endstop_home / trsync (klippy/mcu.py, src/endstop.c): the device samples the switch
// every sample_ticks, and after sample_count consecutive triggered samples it stops that motor's
// steps (its queue is flushed, and further QUEUE_STEPS for it are dropped until the host disarms)
// and reports the clock and step position of the first triggered sample. The host computes the
// position from those (drivers/host/homing.hpp).
//   host -> device  ENDSTOP_HOME     arm (sample_ticks > 0) or disarm (sample_ticks == 0) one motor;
//                                    an optional trailing source byte says what triggers it (the
//                                    switch input when absent: the first v3 form decodes unchanged)
//                   ENDSTOP_QUERY    the pin's state now (M119)
//   device -> host  ENDSTOP_TRIGGER  the trigger (once per arming)
//                   ENDSTOP_STATE    the answer to ENDSTOP_QUERY
// Every encode_* returns the size (type byte included), 0 when it does not fit; every decode_*
// takes the whole payload and returns false on a wrong type, truncation or trailing bytes.
#pragma once

#include <cstddef>
#include <cstdint>

#include "drivers/protocol/messages.hpp"

namespace feedloop::protocol {

// What triggers an armed motor (ENDSTOP_HOME's optional last byte).
enum class EndstopSource : uint8_t {
  kPin = 0,  // the motor's endstop input at trigger_level (the only source of the first v3 form)
  // Trigger at once, when the message arrives: the motor's steps stop there and ENDSTOP_TRIGGER
  // reports its step position (trigger = stop). The host relays another motor's trigger with it
  // (a CoreXY carriage's switch stops the second motor: Klipper's trsync_trigger from the host),
  // and a motor at rest reports its step position with it.
  kNow = 1,
  // The motor's encoder index (its reference mark) at trigger_level: an encoder-index homing's
  // last phase (docs/homing.md "Encoder-index homing"). An MCU whose encoder has no index line
  // never triggers on it.
  kEncoderIndex = 2,
  // A stall (sensorless homing against a hard stop): the encoder stops following the steps. The
  // motor's steps since arming times counts_per_step, less the encoder's counts since arming,
  // beyond threshold_counts (either sign) is a triggered sample. Two varints follow the flags byte
  // (encoded always with this source): counts_per_step_q16 and threshold_counts.
  kStall = 3,
};
constexpr uint8_t kEndstopSourceCount = 4;

struct EndstopHomeMsg {
  uint8_t axis = 0;
  uint8_t trigger_level = 1;  // pin value that means "triggered"
  uint32_t sample_ticks = 0;  // sampling period; 0 disarms (and ends a triggered state)
  uint8_t sample_count = 1;   // consecutive triggered samples needed (debounce), >= 1
  EndstopSource source = EndstopSource::kPin;  // encoded only when not kPin (or with flags)
  // Protocol v4: the optional byte after the source. kReportEncoder: ENDSTOP_TRIGGER carries the
  // motor's encoder count at the first triggered sample (a carriage-referenced homing,
  // docs/homing.md). Encoded only when not 0 (then the source byte is encoded too).
  uint8_t flags = 0;
  uint32_t stall_counts_per_step_q16 = 0;  // kStall: encoder counts per motor step, 16.16
  uint32_t stall_threshold_counts = 0;     // kStall: the divergence that is a stall, > 0
};
inline constexpr uint8_t kEndstopReportEncoder = 0x01;
inline constexpr uint8_t kEndstopKnownFlags = kEndstopReportEncoder;

struct EndstopQueryMsg {
  uint8_t axis = 0;
};

struct EndstopTriggerMsg {
  uint8_t axis = 0;
  int64_t trigger_clock = 0;  // first triggered sample
  int64_t trigger_steps = 0;  // the motor's step position at that sample
  int64_t stop_clock = 0;     // when the steps were stopped (after sample_count samples)
  int64_t stop_steps = 0;     // the step position the motor stopped at
  // Protocol v4, when the arming asked for it (kEndstopReportEncoder): the encoder count at
  // trigger_clock, a trailing zz.
  bool has_encoder = false;
  int64_t trigger_encoder_counts = 0;
};

struct EndstopStateMsg {
  uint8_t axis = 0;
  uint8_t pin = 0;  // the pin's level now (MotorPort::read_endstop)
  uint8_t armed = 0;
  uint8_t triggered = 0;  // armed and tripped, waiting for the host to disarm
};

inline size_t encode_endstop_home(const EndstopHomeMsg& m, uint8_t* buf, size_t cap) {
  MsgWriter w(buf, cap);
  w.u8(static_cast<uint8_t>(MsgType::kEndstopHome))
      .u8(m.axis)
      .u8(m.trigger_level)
      .var(m.sample_ticks)
      .u8(m.sample_count);
  const bool stall = m.source == EndstopSource::kStall;
  if (m.source != EndstopSource::kPin || m.flags != 0) w.u8(static_cast<uint8_t>(m.source));
  if (m.flags != 0 || stall) w.u8(m.flags);
  if (stall) w.var(m.stall_counts_per_step_q16).var(m.stall_threshold_counts);
  return w.ok() ? w.size() : 0;
}
inline bool decode_endstop_home(const uint8_t* p, size_t n, EndstopHomeMsg& out) {
  MsgReader r(p, n);
  if (r.u8() != static_cast<uint8_t>(MsgType::kEndstopHome)) return false;
  out.axis = r.u8();
  out.trigger_level = r.u8();
  const uint64_t ticks = r.var();
  out.sample_count = r.u8();
  if (ticks > UINT32_MAX) return false;
  out.sample_ticks = static_cast<uint32_t>(ticks);
  out.source = EndstopSource::kPin;
  if (r.ok() && !r.at_end()) {
    const uint8_t src = r.u8();
    if (src >= kEndstopSourceCount) return false;  // a source this device does not know
    out.source = static_cast<EndstopSource>(src);
  }
  out.flags = 0;
  if (r.ok() && !r.at_end()) {
    out.flags = r.u8();
    if ((out.flags & ~kEndstopKnownFlags) != 0) return false;  // a flag this device does not know
  }
  out.stall_counts_per_step_q16 = out.stall_threshold_counts = 0;
  if (out.source == EndstopSource::kStall) {
    const uint64_t cps = r.var(), thr = r.var();
    if (cps == 0 || cps > UINT32_MAX || thr == 0 || thr > UINT32_MAX) return false;
    out.stall_counts_per_step_q16 = static_cast<uint32_t>(cps);
    out.stall_threshold_counts = static_cast<uint32_t>(thr);
  }
  return r.ok() && r.at_end();
}

inline size_t encode_endstop_query(const EndstopQueryMsg& m, uint8_t* buf, size_t cap) {
  MsgWriter w(buf, cap);
  w.u8(static_cast<uint8_t>(MsgType::kEndstopQuery)).u8(m.axis);
  return w.ok() ? w.size() : 0;
}
inline bool decode_endstop_query(const uint8_t* p, size_t n, EndstopQueryMsg& out) {
  MsgReader r(p, n);
  if (r.u8() != static_cast<uint8_t>(MsgType::kEndstopQuery)) return false;
  out.axis = r.u8();
  return r.ok() && r.at_end();
}

inline size_t encode_endstop_trigger(const EndstopTriggerMsg& m, uint8_t* buf, size_t cap) {
  MsgWriter w(buf, cap);
  w.u8(static_cast<uint8_t>(MsgType::kEndstopTrigger))
      .u8(m.axis)
      .var(static_cast<uint64_t>(m.trigger_clock))
      .zz(m.trigger_steps)
      .var(static_cast<uint64_t>(m.stop_clock))
      .zz(m.stop_steps);
  if (m.has_encoder) w.zz(m.trigger_encoder_counts);
  return w.ok() ? w.size() : 0;
}
inline bool decode_endstop_trigger(const uint8_t* p, size_t n, EndstopTriggerMsg& out) {
  MsgReader r(p, n);
  if (r.u8() != static_cast<uint8_t>(MsgType::kEndstopTrigger)) return false;
  out.axis = r.u8();
  out.trigger_clock = static_cast<int64_t>(r.var());
  out.trigger_steps = r.zz();
  out.stop_clock = static_cast<int64_t>(r.var());
  out.stop_steps = r.zz();
  out.has_encoder = r.ok() && !r.at_end();
  out.trigger_encoder_counts = out.has_encoder ? r.zz() : 0;
  return r.ok() && r.at_end();
}

inline size_t encode_endstop_state(const EndstopStateMsg& m, uint8_t* buf, size_t cap) {
  MsgWriter w(buf, cap);
  w.u8(static_cast<uint8_t>(MsgType::kEndstopState))
      .u8(m.axis)
      .u8(m.pin)
      .u8(m.armed)
      .u8(m.triggered);
  return w.ok() ? w.size() : 0;
}
inline bool decode_endstop_state(const uint8_t* p, size_t n, EndstopStateMsg& out) {
  MsgReader r(p, n);
  if (r.u8() != static_cast<uint8_t>(MsgType::kEndstopState)) return false;
  out.axis = r.u8();
  out.pin = r.u8();
  out.armed = r.u8();
  out.triggered = r.u8();
  return r.ok() && r.at_end();
}

}  // namespace feedloop::protocol
