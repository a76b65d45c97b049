// The device side of the MCU protocol, written once as portable C++ with fixed buffers (no heap
// anywhere): the "virtual MCU" of DESIGN.md. One instance per axis (the thesis's one-MCU-per-axis
// architecture) or per board with up to kMaxAxes motors, each with its own step queue, MotorPort
// and encoder. It
//  - keeps its own tick clock, which runs at clock_hz * (1 + drift_ppm 1e-6) from an offset,
//  - executes a queue of compressed step runs (drivers/stepgen/step_run.hpp) at their clocks,
//    calling device::MotorPort::step with the true time of each step,
//  - samples its encoder every encoder_period_ticks and reports batches of samples,
//  - (v3) samples an armed endstop and stops that motor's steps at its trigger (homing),
//  - (v3, optional) hosts a HeaterBoard (heater_board.hpp): CONFIGURE_HEATER / SET_HEATER / SET_FAN
//    go to it, its HEATER_REPORT / HEATER_FAULT go out in frames; a stop turns its heaters off,
//  - answers identify / clock queries / status queries, enables and disables the driver,
//  - stops (queue flushed, driver disabled, error reported) on a queue underrun (a batch whose
//    first step is already in the past), a watchdog timeout (no message from the host for
//    watchdog_ticks while enabled), an emergency stop or a protocol version mismatch.
// It is driven in virtual time: receive(bytes, t) and run_until(t) process everything due up to
// the true time t (seconds); pop_frame() hands out what it transmits.
// Owner: one thread (the simulator's, or feedloop-vmcu's main loop).
#pragma once

#include <cstddef>
#include <cstdint>

#include "drivers/device/axis_loop.hpp"
#include "drivers/device/motor_port.hpp"
#include "drivers/protocol/messages.hpp"
#include "drivers/protocol/reliable_link.hpp"
#include "drivers/stepgen/step_run.hpp"

namespace feedloop::device {

class HeaterBoard;

struct VirtualMcuParams {
  double clock_hz = 20e6;     // nominal tick rate (reported to the host)
  double drift_ppm = 0.0;     // true rate = clock_hz * (1 + drift_ppm * 1e-6)
  double offset_s = 0.0;      // clock(t) = (t + offset_s) * true rate
  uint8_t axis = 0;           // informational (reported in IDENTIFY_RESPONSE with one motor)
  char name[16] = "mcu";
  // Versions the device accepts from a host: [min_protocol_version, protocol_version]. It answers
  // IDENTIFY with the host's version when that is in range (so a v1 host works with this v2
  // device), else with protocol_version and a version-mismatch error. min_protocol_version 0:
  // protocol::kMinProtocolVersion for this build's version; a device set to another version (tests
  // emulating other firmware) speaks only that one.
  uint16_t protocol_version = protocol::kProtocolVersion;
  uint16_t min_protocol_version = 0;
  // LOOP_REPORT's per-tick cost: the host's steady clock around each loop tick (ns). false: 0.
  bool measure_tick_cost = true;
  protocol::LinkParams link;
};

struct AxisStatus {
  uint64_t steps_executed = 0;
  int64_t position_steps = 0;
  uint64_t step_hash = 0;            // FNV-1a over (clock, direction) of every executed step
  uint32_t queued_runs = 0;
  int64_t device_steps = 0;          // net steps issued by the device loop (corrections, stop ramps)
  uint64_t device_steps_executed = 0;
};

struct VirtualMcuStatus {
  // Totals / axis 0 (the one-MCU-per-axis case); per motor in axes[].
  uint64_t steps_executed = 0;
  int64_t position_steps = 0;
  uint64_t step_hash = 0;
  uint32_t queued_runs = 0;
  AxisStatus axes[4];
  int num_axes = 1;
  bool identified = false;
  bool enabled = false;
  bool stopped = false;
  protocol::McuError last_error = protocol::McuError::kNone;
  protocol::McuError stop_reason = protocol::McuError::kNone;  // why the device last stopped
  uint64_t errors = 0;
  uint64_t reports_dropped = 0;
  uint64_t frames_dropped = 0;
  uint16_t negotiated_version = 0;   // the version agreed at the last IDENTIFY (0: none)
};

// FNV-1a step hash, shared with the host side so it can check what the device executed.
inline uint64_t step_hash_update(uint64_t h, int64_t clock, int direction) {
  const uint64_t v[2] = {static_cast<uint64_t>(clock), static_cast<uint64_t>(direction > 0 ? 1 : 2)};
  for (uint64_t x : v)
    for (int i = 0; i < 8; ++i) {
      h ^= (x >> (8 * i)) & 0xFF;
      h *= 1099511628211ull;
    }
  return h;
}
inline constexpr uint64_t kStepHashSeed = 1469598103934665603ull;

class VirtualMcu final : private protocol::FrameOutput, private protocol::PayloadHandler {
 public:
  static constexpr int kMaxAxes = 4;
  static constexpr int kMaxRuns = 4096;  // per axis
  static constexpr int kMaxOutFrames = 64;
  static constexpr int kMaxPending = 16;
  static constexpr int kMaxSamples = 64;

  // One motor.
  VirtualMcu(const VirtualMcuParams& params, MotorPort* port);
  // Several motors (a board): ports[0..num_axes), num_axes <= kMaxAxes; QUEUE_STEPS' axis byte
  // selects the motor. heaters (optional, not owned, outlives the MCU): the heaters and fans this
  // MCU drives (protocol v3); its clock_hz must be params.clock_hz and its ports get
  // clock / clock_hz as their time (so give such an MCU offset_s 0 and drift_ppm 0 in simulation).
  // A port may be nullptr (a heater-only MCU: one motor slot, no motor).
  VirtualMcu(const VirtualMcuParams& params, MotorPort* const* ports, int num_axes,
             HeaterBoard* heaters = nullptr);

  // Bytes from the host that arrive at true time t_s (everything due before is processed first).
  void receive(const uint8_t* data, size_t n, double t_s);
  // Executes steps, encoder samples, the watchdog and retransmissions due up to true time t_s.
  void run_until(double t_s);
  // Next frame the device transmits; false when none. out must hold protocol::kMaxFrame bytes.
  bool pop_frame(uint8_t* out, size_t& n);

  int64_t clock_at(double t_s) const;
  double true_time_at(int64_t clock) const;
  const VirtualMcuStatus& status() const { return status_; }
  const VirtualMcuParams& params() const { return params_; }
  const protocol::LinkStats& link_stats() const { return link_.stats(); }
  // The device loop of motor i (protocol v2; idle until CONFIGURE_LOOP).
  const AxisLoop& loop(int i) const { return axes_[i].loop; }
  // True time of the next thing the device must do by itself (step, sample, watchdog,
  // retransmission); a large value when idle. Lets a real-time loop sleep until then.
  double next_event_time() const;

 private:
  void write_frame(const uint8_t* frame, size_t n) override;
  void on_payload(const uint8_t* p, size_t n) override;
  struct QueuedRun {
    int64_t start_clock;
    stepgen::StepRun run;
  };
  struct Axis {
    MotorPort* port = nullptr;
    QueuedRun runs[kMaxRuns];
    int run_head = 0, run_count = 0;
    int64_t queued_end_clock = 0;  // clock of the last queued step
    bool have_queued_end = false;
    int64_t last_step_clock = 0, next_step_clock = 0, interval = 0;
    uint32_t run_k = 0;  // steps of the head run already executed
    AxisStatus st;
    int64_t sample_first_clock = 0;
    int64_t samples[kMaxSamples] = {};
    // Device loop (protocol v2) and its extra steps, spread evenly over a control period.
    AxisLoop loop;
    float step_fraction = 0.0f;  // applied to the port (the loop's sub_step_trim)
    int32_t extra_left = 0, extra_n = 0, extra_k = 0;
    int64_t extra_start = 0, extra_span = 0, extra_next_clock = 0;
    // Endstop (protocol v3): sampled every endstop_ticks while armed; after endstop_count
    // consecutive triggered samples the motor's steps stop and the trigger is reported.
    bool es_armed = false, es_triggered = false;
    uint8_t es_level = 1, es_count = 1, es_seen = 0;
    int64_t es_ticks = 0, es_next_clock = 0;
    int64_t es_first_clock = 0, es_first_steps = 0;
    bool es_report_encoder = false;  // v4: the encoder count at the first triggered sample
    bool es_index = false;           // the source is the encoder's index line, not the pin
    bool es_stall = false;           // the source is a stall: the encoder stops following the steps
    int64_t es_stall_cps_q16 = 0, es_stall_threshold = 0, es_stall_steps0 = 0, es_stall_enc0 = 0;
    int64_t es_first_encoder = 0;
  };
  void handle_queue_steps(protocol::MsgReader& r);
  void handle_configure_loop(const uint8_t* p, size_t n);
  void handle_queue_target(const uint8_t* p, size_t n);
  void handle_endstop_home(const uint8_t* p, size_t n);
  void handle_endstop_query(const uint8_t* p, size_t n);
  void handle_heater_message(uint8_t type, const uint8_t* p, size_t n);
  void send_heater_messages();
  void endstop_sample(int axis);
  void endstop_trigger(int axis, int64_t at);
  void loop_tick(int axis);
  void do_extra_step(Axis& a);
  void send_loop_events(int axis);
  // A controlled stop of every axis with an active loop (the others' queues are flushed now).
  void begin_controlled_stop(StopReason why, protocol::McuError code, int64_t detail);
  void sync_status();
  // Sends now or queues behind the window; `droppable` messages (encoder reports) give way when
  // the queue is half full, so error reports and replies always find room.
  void send_msg(const uint8_t* p, size_t n, bool droppable = false);
  void flush_pending();
  void send_error(protocol::McuError code, int64_t detail);
  void send_status();
  void send_encoder_report(int axis);
  void stop(protocol::McuError code, int64_t detail);
  void do_step(Axis& a);
  void activate_head(Axis& a);
  int64_t now_ns() const;

  VirtualMcuParams params_;
  double rate_hz_;  // true tick rate
  protocol::ReliableLink link_;
  VirtualMcuStatus status_;
  int64_t now_clock_ = 0;

  // Per-motor step queues (rings) and the runs being executed.
  Axis axes_[kMaxAxes];
  int num_axes_ = 1;

  // Encoder sampling (all motors sampled together).
  int64_t encoder_period_ticks_ = 0;
  int samples_per_report_ = 10;
  int64_t next_sample_clock_ = 0;
  int nsamples_ = 0;

  HeaterBoard* heaters_ = nullptr;  // optional (protocol v3 heaters and fans)

  // Watchdog.
  int64_t watchdog_ticks_ = 0;
  int64_t last_host_clock_ = 0;

  // A controlled stop in progress: the error reported once every loop axis is at rest.
  bool loop_stopping_ = false;
  protocol::McuError stop_code_ = protocol::McuError::kNone;
  int64_t stop_detail_ = 0;
  uint16_t negotiated_version_ = 0;

  // Outgoing frames and messages waiting for window space.
  uint8_t out_frames_[kMaxOutFrames][protocol::kMaxFrame] = {};
  size_t out_len_[kMaxOutFrames] = {};
  int out_head_ = 0, out_count_ = 0;
  uint8_t pending_[kMaxPending][protocol::kMaxPayload] = {};
  size_t pending_len_[kMaxPending] = {};
  int pending_head_ = 0, pending_count_ = 0;
};

}  // namespace feedloop::device
