// Protocol v2: the device loop's messages (docs/protocol.md, "Protocol v2: the device loop").
// Encoders and decoders for both sides, allocation-free, over caller buffers:
//   host -> device  CONFIGURE_LOOP  gains, limits, model of one axis, active from an MCU clock
//                   QUEUE_TARGET    knots of r(t) (piecewise linear, target_codec.hpp compresses)
//   device -> host  LOOP_REPORT     telemetry: r, y, e, correction, loop steps, tick cost, counters
//                   LOOP_EVENT      slips, trips, encoder faults, stops, activations
// Every encode_* returns the message size (type byte included), 0 when it does not fit `cap`;
// every decode_* takes the whole payload (type byte included) and returns false on a wrong type,
// truncation or trailing bytes.
#pragma once

#include <cstddef>
#include <cstdint>

#include "drivers/device/axis_loop.hpp"
#include "drivers/device/loop_params.hpp"
#include "drivers/device/target_queue.hpp"
#include "drivers/protocol/messages.hpp"

namespace feedloop::protocol {

struct ConfigureLoopMsg {
  uint8_t axis = 0;               // motor index on the MCU
  int64_t activation_clock = 0;   // MCU clock from which the set applies (first tick at or after it)
  device::LoopParams params;
};

struct LoopReportMsg {
  uint8_t axis = 0;
  device::LoopReport report;
};

struct LoopEventMsg {
  uint8_t axis = 0;
  device::LoopEvent event;
};

size_t encode_configure_loop(const ConfigureLoopMsg& m, uint8_t* buf, size_t cap);
bool decode_configure_loop(const uint8_t* p, size_t n, ConfigureLoopMsg& out);

// QUEUE_TARGET with knots[0..count): clocks strictly increasing. At most
// max_target_knots_per_message(...) fit one frame; split longer runs over several messages.
size_t encode_queue_target(uint8_t axis, const device::TargetKnot* knots, int count, uint8_t* buf, size_t cap);

// Reads QUEUE_TARGET knot by knot without a buffer: begin() checks the header, next() yields the
// knots, ok() is false after a malformed body.
class QueueTargetReader {
 public:
  bool begin(const uint8_t* p, size_t n);
  uint8_t axis() const { return axis_; }
  int count() const { return count_; }
  bool next(device::TargetKnot& k);  // false when done or malformed (then !ok())
  bool ok() const { return ok_; }

 private:
  const uint8_t* p_ = nullptr;
  size_t n_ = 0, pos_ = 0;
  uint8_t axis_ = 0;
  int count_ = 0, read_ = 0;
  bool ok_ = false;
  device::TargetKnot last_;
};

size_t encode_loop_report(const LoopReportMsg& m, uint8_t* buf, size_t cap);
bool decode_loop_report(const uint8_t* p, size_t n, LoopReportMsg& out);

size_t encode_loop_event(const LoopEventMsg& m, uint8_t* buf, size_t cap);
bool decode_loop_event(const uint8_t* p, size_t n, LoopEventMsg& out);

const char* loop_event_name(device::LoopEventKind k);
const char* stop_reason_name(device::StopReason r);

}  // namespace feedloop::protocol
