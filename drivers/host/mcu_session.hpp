// Host side of the link to one MCU: identify (protocol version check), configure, clock
// synchronisation by periodic clock queries, step batches queued and sent as the window allows,
// heartbeats, encoder samples and device status/errors coming back, and disconnect/reconnect
// through the Transport. A device that acknowledges nothing for link_stall_s while frames are in
// flight (it rebooted and lost the link state, or hangs) fails the session with a message naming
// the MCU; start() again re-identifies it.
// Real time: in steady streaming (queue_steps, poll, acks, clock queries, encoder reports,
// take_encoder_samples(out)) it allocates nothing: fixed rings for outgoing messages and clock
// queries, sample buffers reserved up front. Events, errors, start() and status replies may
// allocate. It never waits on the transport: frames go out through Transport::try_write() (a
// full send queue is counted and the link retransmits later), received bytes carry the I/O
// thread's arrival stamps, and the clock sync's fit runs on the transport's I/O thread when it
// has one (ClockSyncChannel). Owner: the servo thread (McuBridge), a test or the batch-mode
// pipeline thread.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "drivers/clock_sync_channel.hpp"
#include "drivers/protocol/endstop_messages.hpp"
#include "drivers/protocol/heater_messages.hpp"
#include "drivers/protocol/loop_messages.hpp"
#include "drivers/protocol/messages.hpp"
#include "drivers/protocol/reliable_link.hpp"
#include "drivers/stepgen/step_batcher.hpp"
#include "drivers/transport.hpp"

namespace feedloop::drivers {

struct McuSessionParams {
  std::string name = "mcu";
  protocol::LinkParams link;
  uint16_t protocol_version = protocol::kProtocolVersion;  // tests set another one
  double clock_query_period_s = 0.1;
  int clock_query_burst = 8;          // queries 10 ms apart right after identify
  double heartbeat_period_s = 0.1;
  double encoder_period_s = 1e-3;     // 0 = no encoder sampling
  int samples_per_report = 10;
  double watchdog_s = 0.5;            // 0 = no watchdog
  double reconnect_period_s = 0.25;
  double link_stall_s = 1.0;          // no acknowledgement progress this long -> kFailed (0 = never)
};

enum class McuState { kIdle, kIdentifying, kReady, kDisconnected, kFailed };

struct EncoderSample {
  int axis = 0;  // motor index on the MCU
  int64_t clock = 0;
  int64_t counts = 0;
};

// A heater message from the device (protocol v3: HEATER_REPORT or HEATER_FAULT), as it arrived
// (checked by its decoder): the payload bytes.
struct HeaterPayload {
  uint8_t n = 0;
  uint8_t bytes[24] = {};
};

struct AxisDeviceStatus {
  uint64_t steps_executed = 0;
  int64_t position_steps = 0;
  uint64_t queued_runs = 0;
  uint64_t step_hash = 0;  // device::step_hash_update over every executed step
};

struct DeviceStatus {
  int64_t clock = 0;
  bool enabled = false;
  bool stopped = false;
  std::vector<AxisDeviceStatus> axes;  // one per motor of the MCU
  // Motor 0 (the one-MCU-per-axis case).
  uint64_t steps_executed = 0;
  int64_t position_steps = 0;
  uint64_t queued_runs = 0;
  uint64_t step_hash = 0;
};

class McuSession final : private protocol::FrameOutput, private protocol::PayloadHandler {
 public:
  static constexpr int kOutboxMessages = 256;  // messages waiting for the link window
  static constexpr int kMaxQueries = 64;       // clock queries awaiting their reply
  static constexpr size_t kSampleCapacity = 4096;  // encoder samples kept until taken

  // The session must not outlive its transport.
  McuSession(const McuSessionParams& params, Transport& transport);
  ~McuSession() override;
  McuSession(const McuSession&) = delete;
  McuSession& operator=(const McuSession&) = delete;

  // Opens the transport, resets the link and sends IDENTIFY.
  Status start(double now_s);
  // Transport I/O, retransmissions, queued messages, clock queries, heartbeats, reconnects.
  void poll(double now_s);

  McuState state() const { return state_; }
  bool ready() const { return state_ == McuState::kReady; }
  // Set when state() is kFailed: says which MCU and why.
  const std::optional<Error>& error() const { return error_; }

  // Queues a batch for the MCU. A batch that does not fit a frame (body > kMaxPayload - 2 bytes)
  // or finds the outbox full fails the session (no step is dropped silently).
  void queue_steps(const stepgen::StepBatch& batch);
  void set_enabled(bool on);
  void emergency_stop();
  void request_status();
  // Nothing waiting to be sent and nothing unacknowledged.
  bool idle() const { return out_count_ == 0 && link_.in_flight() == 0; }

  // The latest clock estimate (taken from the I/O thread's fit at each poll()).
  const ClockEstimate& clock() const { return clock_.estimate(); }
  stepgen::TickMap tick_map() const { return clock_.estimate().tick_map(); }
  // True when the clock fit runs on the transport's I/O thread.
  bool clock_fit_async() const { return clock_.async(); }
  // Encoder samples since the last call, oldest first. This form allocates a new vector each call.
  std::vector<EncoderSample> take_encoder_samples();
  // Real-time form: out is cleared and swapped with the session's buffer (both keep at least
  // kSampleCapacity of capacity, so steady use allocates nothing). Returns out.size().
  size_t take_encoder_samples(std::vector<EncoderSample>& out);
  // Samples dropped because nobody took them (more than kSampleCapacity waiting).
  uint64_t encoder_samples_dropped() const { return samples_dropped_; }
  // Human-readable events (errors reported by the MCU, disconnects, reconnects), oldest first.
  std::vector<std::string> take_events();
  const std::optional<DeviceStatus>& last_status() const { return status_; }
  uint64_t bytes_written() const { return bytes_written_; }
  uint64_t frames_written() const { return frames_written_; }
  // Frames the transport's send queue refused (back pressure; the link sent them again later).
  uint64_t frames_refused() const { return frames_refused_; }
  const protocol::LinkStats& link_stats() const { return link_.stats(); }
  const protocol::FrameDecoderStats& decoder_stats() const { return link_.decoder_stats(); }
  int frames_in_flight() const { return link_.in_flight(); }
  uint32_t mcu_clock_hz() const { return mcu_clock_hz_; }
  int mcu_axes() const { return mcu_axes_; }
  // The protocol version agreed at identify (0 before): 2 when the device loop's messages
  // (drivers/protocol/loop_messages.hpp) may be sent, 1 with an older device.
  uint16_t negotiated_version() const { return negotiated_version_; }
  // Queues an already encoded message (e.g. encode_configure_loop, encode_queue_target) behind the
  // others; fails the session when the outbox is full, like queue_steps. RT-safe.
  void queue_message(const uint8_t* msg, size_t n);
  // Loop reports and events (protocol v2) since the last call, oldest first (fixed rings of
  // kLoopMessages each; the oldest are dropped and counted when nobody takes them).
  size_t take_loop_reports(protocol::LoopReportMsg* out, size_t cap);
  size_t take_loop_events(protocol::LoopEventMsg* out, size_t cap);
  uint64_t loop_messages_dropped() const { return loop_dropped_; }
  // Endstops (protocol v3; endstop_messages.hpp): encode ENDSTOP_HOME / ENDSTOP_QUERY and send them
  // with queue_message; the device's ENDSTOP_TRIGGER and ENDSTOP_STATE since the last call, oldest
  // first (fixed rings of kEndstopMessages; the oldest are dropped when nobody takes them).
  size_t take_endstop_triggers(protocol::EndstopTriggerMsg* out, size_t cap);
  size_t take_endstop_states(protocol::EndstopStateMsg* out, size_t cap);
  // Heaters (protocol v3; heater_messages.hpp): encode CONFIGURE_HEATER / SET_HEATER / SET_FAN and
  // send them with queue_message; the device's HEATER_REPORT and HEATER_FAULT since the last call,
  // oldest first (a fixed ring of kHeaterMessages; the oldest are dropped when nobody takes them).
  size_t take_heater_messages(HeaterPayload* out, size_t cap);

 private:
  void write_frame(const uint8_t* frame, size_t n) override;
  void on_payload(const uint8_t* p, size_t n) override;
  // Room for one more message at the back (or the front) of the outbox; nullptr (and the session
  // failed) when it is full.
  uint8_t* outbox_slot(size_t n, bool front = false);
  void enqueue(const uint8_t* msg, size_t n, bool front = false);
  void send_clock_query();
  void fail(std::string message);
  std::string io_stall_note() const;
  void mark_disconnected(const std::string& why);
  int64_t ns(double s) const { return static_cast<int64_t>(s * 1e9); }

  McuSessionParams p_;
  Transport& transport_;
  protocol::ReliableLink link_;
  ClockSyncChannel clock_;
  McuState state_ = McuState::kIdle;
  McuState state_before_disconnect_ = McuState::kIdle;
  std::optional<Error> error_;
  // Outgoing messages waiting for window space (a ring; emergency stop and configure jump it).
  struct OutMsg {
    size_t n = 0;
    uint8_t bytes[protocol::kMaxPayload] = {};
  };
  std::array<OutMsg, kOutboxMessages> outbox_{};
  int out_head_ = 0, out_count_ = 0;
  double now_s_ = 0.0;
  double next_query_s_ = 0.0, last_send_s_ = 0.0, next_reconnect_s_ = 0.0;
  int burst_left_ = 0;
  uint64_t next_token_ = 1;
  struct Query {
    uint64_t token = 0;
    double sent_s = 0.0;     // when the session queued it
    uint64_t ticket = 0;     // the transport's frame number (its departure stamp), if has_ticket
    bool has_ticket = false;
  };
  bool capture_ticket_ = false, captured_ = false;  // send_clock_query -> write_frame
  uint64_t captured_ticket_ = 0;
  double rx_time_s_ = 0.0;  // arrival of the bytes being decoded (the transport's stamp or now)
  std::array<Query, kMaxQueries> queries_{};  // ring, oldest at query_head_
  int query_head_ = 0, query_count_ = 0;
  uint32_t mcu_clock_hz_ = 0;
  int mcu_axes_ = 1;
  uint16_t identify_version_ = 0;
  uint16_t negotiated_version_ = 0;
  static constexpr size_t kLoopMessages = 256;
  std::array<protocol::LoopReportMsg, kLoopMessages> loop_reports_{};
  size_t report_head_ = 0, report_count_ = 0;
  std::array<protocol::LoopEventMsg, kLoopMessages> loop_events_{};
  size_t event_head_ = 0, event_count_ = 0;
  uint64_t loop_dropped_ = 0;
  static constexpr size_t kEndstopMessages = 16;
  std::array<protocol::EndstopTriggerMsg, kEndstopMessages> es_triggers_{};
  size_t es_trigger_head_ = 0, es_trigger_count_ = 0;
  std::array<protocol::EndstopStateMsg, kEndstopMessages> es_states_{};
  size_t es_state_head_ = 0, es_state_count_ = 0;
  static constexpr size_t kHeaterMessages = 64;
  std::array<HeaterPayload, kHeaterMessages> heater_msgs_{};
  size_t heater_head_ = 0, heater_count_ = 0;
  std::vector<EncoderSample> samples_;
  uint64_t samples_dropped_ = 0;
  std::vector<std::string> events_;
  std::optional<DeviceStatus> status_;
  DeviceStatus status_scratch_;
  uint64_t bytes_written_ = 0, frames_written_ = 0, frames_refused_ = 0;
  double last_refused_s_ = -1e300;
  double io_gap_at_start_ms_ = 0.0;  // the transport's longest I/O thread gap when start() ran
};

}  // namespace feedloop::drivers
