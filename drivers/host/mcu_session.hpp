// Host side of the link to one MCU: identify (protocol version check), configure, clock
// synchronisation by periodic clock queries, step batches queued and sent as the window allows,
// heartbeats, encoder samples and device status/errors coming back, and disconnect/reconnect
// through the Transport. Not real-time (it may allocate); the step path hands it finished
// batches. Owner: the I/O thread (or the batch-mode pipeline thread).
#pragma once

#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <vector>

#include "drivers/clock_sync.hpp"
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
};

enum class McuState { kIdle, kIdentifying, kReady, kDisconnected, kFailed };

struct EncoderSample {
  int axis = 0;  // motor index on the MCU
  int64_t clock = 0;
  int64_t counts = 0;
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
  McuSession(const McuSessionParams& params, Transport& transport);

  // Opens the transport, resets the link and sends IDENTIFY.
  Status start(double now_s);
  // Transport I/O, retransmissions, queued messages, clock queries, heartbeats, reconnects.
  void poll(double now_s);

  McuState state() const { return state_; }
  bool ready() const { return state_ == McuState::kReady; }
  // Set when state() is kFailed: says which MCU and why.
  const std::optional<Error>& error() const { return error_; }

  void queue_steps(const stepgen::StepBatch& batch);
  void set_enabled(bool on);
  void emergency_stop();
  void request_status();
  // Nothing waiting to be sent and nothing unacknowledged.
  bool idle() const { return outbox_.empty() && link_.in_flight() == 0; }

  const ClockSync& clock() const { return clock_; }
  stepgen::TickMap tick_map() const { return clock_.tick_map(); }
  std::vector<EncoderSample> take_encoder_samples();
  // Human-readable events (errors reported by the MCU, disconnects, reconnects), oldest first.
  std::vector<std::string> take_events();
  const std::optional<DeviceStatus>& last_status() const { return status_; }
  uint64_t bytes_written() const { return bytes_written_; }
  uint64_t frames_written() const { return frames_written_; }
  const protocol::LinkStats& link_stats() const { return link_.stats(); }
  uint32_t mcu_clock_hz() const { return mcu_clock_hz_; }
  int mcu_axes() const { return mcu_axes_; }

 private:
  void write_frame(const uint8_t* frame, size_t n) override;
  void on_payload(const uint8_t* p, size_t n) override;
  void enqueue(std::vector<uint8_t> msg) { outbox_.push_back(std::move(msg)); }
  void send_clock_query();
  void fail(std::string message);
  void mark_disconnected(const std::string& why);
  int64_t ns(double s) const { return static_cast<int64_t>(s * 1e9); }

  McuSessionParams p_;
  Transport& transport_;
  protocol::ReliableLink link_;
  ClockSync clock_;
  McuState state_ = McuState::kIdle;
  McuState state_before_disconnect_ = McuState::kIdle;
  std::optional<Error> error_;
  std::deque<std::vector<uint8_t>> outbox_;
  double now_s_ = 0.0;
  double next_query_s_ = 0.0, last_send_s_ = 0.0, next_reconnect_s_ = 0.0;
  int burst_left_ = 0;
  uint64_t next_token_ = 1;
  std::deque<std::pair<uint64_t, double>> queries_;  // token, send time
  uint32_t mcu_clock_hz_ = 0;
  int mcu_axes_ = 1;
  std::vector<EncoderSample> samples_;
  std::vector<std::string> events_;
  std::optional<DeviceStatus> status_;
  uint64_t bytes_written_ = 0, frames_written_ = 0;
};

}  // namespace feedloop::drivers
