// Host session with one MCU: see mcu_session.hpp.
#include "drivers/host/mcu_session.hpp"

#include "drivers/device/loop_params.hpp"  // loop_param_error_name
#include "drivers/device/virtual_mcu.hpp"  // kMaxAxes

#include <cmath>
#include <cstdint>  // UINT32_MAX
#include <cstring>  // memcpy

namespace feedloop::drivers {

using protocol::McuError;
using protocol::MsgReader;
using protocol::MsgType;
using protocol::MsgWriter;

McuSession::McuSession(const McuSessionParams& params, Transport& transport)
    : p_(params), transport_(transport) {
  // A fresh epoch per session object, so a restarted host is told apart from a retransmission.
  protocol::LinkParams lp = p_.link;
  lp.initial_epoch = static_cast<int>(reinterpret_cast<uintptr_t>(this) >> 4) & 0x0F;
  link_.configure(lp, this, this);
  clock_.set_async(transport_.run_on_io_thread(&clock_));
  clock_.configure({});
  samples_.reserve(kSampleCapacity);
  status_scratch_.axes.reserve(device::VirtualMcu::kMaxAxes);
}

McuSession::~McuSession() {
  if (clock_.async()) transport_.run_on_io_thread(nullptr);  // the I/O thread lets go of clock_
}

uint8_t* McuSession::outbox_slot(size_t n, bool front) {
  if (n > protocol::kMaxPayload) {
    fail("MCU '" + p_.name + "' (" + transport_.describe() + "): a message of " + std::to_string(n) +
         " bytes does not fit a frame (at most " + std::to_string(protocol::kMaxPayload) +
         "); configure smaller step batches; motion stopped");
    return nullptr;
  }
  if (out_count_ == kOutboxMessages) {
    fail("MCU '" + p_.name + "' (" + transport_.describe() + "): " + std::to_string(kOutboxMessages) +
         " messages wait for the link (it is too slow or stalled); motion stopped");
    return nullptr;
  }
  int idx;
  if (front) {
    out_head_ = (out_head_ + kOutboxMessages - 1) % kOutboxMessages;
    idx = out_head_;
  } else {
    idx = (out_head_ + out_count_) % kOutboxMessages;
  }
  ++out_count_;
  outbox_[static_cast<size_t>(idx)].n = n;
  return outbox_[static_cast<size_t>(idx)].bytes;
}

void McuSession::enqueue(const uint8_t* msg, size_t n, bool front) {
  if (uint8_t* d = outbox_slot(n, front)) std::memcpy(d, msg, n);
}

Status McuSession::start(double now_s) {
  now_s_ = now_s;
  Status st = transport_.open();
  if (!st.ok()) {
    fail("MCU '" + p_.name + "' (" + transport_.describe() + "): " + st.error().message);
    return *error_;
  }
  link_.reset();
  out_head_ = out_count_ = 0;
  query_head_ = query_count_ = 0;
  io_gap_at_start_ms_ = transport_.io_stats().io_max_gap_us * 1e-3;
  state_ = McuState::kIdentifying;
  error_.reset();
  identify_version_ = p_.protocol_version;
  negotiated_version_ = 0;
  const uint8_t m[3] = {static_cast<uint8_t>(MsgType::kIdentify), static_cast<uint8_t>(p_.protocol_version & 0xFF),
                        static_cast<uint8_t>(p_.protocol_version >> 8)};
  enqueue(m, sizeof m);
  return {};
}

// A stalled I/O thread on this side may explain an underrun, a watchdog or a silent link: " (this
// link's I/O thread did not run for up to N ms)" when it stalled for 100 ms or more (the steps'
// lead: shorter stalls are harmless by design) since start(), else "".
std::string McuSession::io_stall_note() const {
  const double gap_ms = transport_.io_stats().io_max_gap_us * 1e-3;
  if (gap_ms <= io_gap_at_start_ms_ || gap_ms < 100.0) return {};
  return " (this link's I/O thread did not run for up to " + std::to_string(static_cast<int>(gap_ms)) + " ms)";
}

void McuSession::fail(std::string message) {
  state_ = McuState::kFailed;
  error_ = Error{message, {}};
  events_.push_back(std::move(message));
}

void McuSession::mark_disconnected(const std::string& why) {
  if (state_ == McuState::kDisconnected || state_ == McuState::kFailed) return;
  state_before_disconnect_ = state_;
  state_ = McuState::kDisconnected;
  events_.push_back("MCU '" + p_.name + "' (" + transport_.describe() + ") disconnected: " + why);
  next_reconnect_s_ = now_s_ + p_.reconnect_period_s;
}

void McuSession::write_frame(const uint8_t* frame, size_t n) {
  if (state_ == McuState::kDisconnected) return;  // lost; the link retransmits after reconnect
  switch (transport_.try_write(frame, n)) {
    case TxResult::kQueued:
      bytes_written_ += n;
      ++frames_written_;
      last_send_s_ = now_s_;
      if (capture_ticket_) {
        captured_ticket_ = transport_.tx_ticket() - 1;
        captured_ = true;
      }
      return;
    case TxResult::kFull:  // back pressure: counted; the link retransmits the frame after its timeout
      ++frames_refused_;
      last_refused_s_ = now_s_;
      return;
    case TxResult::kTooLong:
      fail("MCU '" + p_.name + "' (" + transport_.describe() + "): a frame of " + std::to_string(n) +
           " bytes is refused by the transport; motion stopped");
      return;
    case TxResult::kDown:
      mark_disconnected(transport_.error_text());
      return;
  }
}

void McuSession::queue_steps(const stepgen::StepBatch& b) {
  uint8_t* m = outbox_slot(2 + b.body_bytes);
  if (m == nullptr) return;
  m[0] = static_cast<uint8_t>(MsgType::kQueueSteps);
  m[1] = b.axis;
  std::memcpy(m + 2, b.body, b.body_bytes);
}

void McuSession::queue_message(const uint8_t* msg, size_t n) { enqueue(msg, n); }

size_t McuSession::take_loop_reports(protocol::LoopReportMsg* out, size_t cap) {
  size_t k = 0;
  while (k < cap && report_count_ > 0) {
    out[k++] = loop_reports_[report_head_];
    report_head_ = (report_head_ + 1) % kLoopMessages;
    --report_count_;
  }
  return k;
}

size_t McuSession::take_loop_events(protocol::LoopEventMsg* out, size_t cap) {
  size_t k = 0;
  while (k < cap && event_count_ > 0) {
    out[k++] = loop_events_[event_head_];
    event_head_ = (event_head_ + 1) % kLoopMessages;
    --event_count_;
  }
  return k;
}

namespace {
// Pops up to cap messages from a ring.
template <typename T, size_t N>
size_t take_ring(std::array<T, N>& ring, size_t& head, size_t& count, T* out, size_t cap) {
  size_t k = 0;
  while (k < cap && count > 0) {
    out[k++] = ring[head];
    head = (head + 1) % N;
    --count;
  }
  return k;
}
template <typename T, size_t N>
void put_ring(std::array<T, N>& ring, size_t& head, size_t& count, const T& m) {
  if (count == N) {  // nobody takes them: keep the newest
    head = (head + 1) % N;
    --count;
  }
  ring[(head + count++) % N] = m;
}
}  // namespace

size_t McuSession::take_heater_messages(HeaterPayload* out, size_t cap) {
  return take_ring(heater_msgs_, heater_head_, heater_count_, out, cap);
}

size_t McuSession::take_endstop_triggers(protocol::EndstopTriggerMsg* out, size_t cap) {
  return take_ring(es_triggers_, es_trigger_head_, es_trigger_count_, out, cap);
}
size_t McuSession::take_endstop_states(protocol::EndstopStateMsg* out, size_t cap) {
  return take_ring(es_states_, es_state_head_, es_state_count_, out, cap);
}

void McuSession::set_enabled(bool on) {
  const uint8_t m[2] = {static_cast<uint8_t>(MsgType::kEnable), static_cast<uint8_t>(on ? 1 : 0)};
  enqueue(m, sizeof m);
}

void McuSession::emergency_stop() {
  // Jumps the queue: nothing queued behind it may move the motor.
  out_head_ = out_count_ = 0;
  const uint8_t m = static_cast<uint8_t>(MsgType::kEmergencyStop);
  enqueue(&m, 1);
}

void McuSession::request_status() {
  const uint8_t m = static_cast<uint8_t>(MsgType::kStatusQuery);
  enqueue(&m, 1);
}

void McuSession::send_clock_query() {
  uint8_t buf[16];
  MsgWriter w(buf, sizeof buf);
  const uint64_t token = next_token_++;
  w.u8(static_cast<uint8_t>(MsgType::kClockQuery)).var(token);
  // Sent directly (not behind step batches) so the round trip is short; the transport's frame
  // number gives its departure stamp.
  capture_ticket_ = true;
  captured_ = false;
  const bool sent = link_.send(buf, w.size(), ns(now_s_));
  capture_ticket_ = false;
  if (!sent) return;
  if (query_count_ == kMaxQueries) {  // the oldest never got its reply: forget it
    query_head_ = (query_head_ + 1) % kMaxQueries;
    --query_count_;
  }
  queries_[static_cast<size_t>((query_head_ + query_count_) % kMaxQueries)] = {token, now_s_, captured_ticket_,
                                                                                captured_};
  ++query_count_;
}

std::vector<EncoderSample> McuSession::take_encoder_samples() {
  std::vector<EncoderSample> out(samples_.begin(), samples_.end());
  samples_.clear();
  return out;
}

size_t McuSession::take_encoder_samples(std::vector<EncoderSample>& out) {
  out.clear();
  if (out.capacity() < kSampleCapacity) out.reserve(kSampleCapacity);  // once per caller buffer
  out.swap(samples_);
  return out.size();
}

std::vector<std::string> McuSession::take_events() {
  std::vector<std::string> out;
  out.swap(events_);
  return out;
}

void McuSession::poll(double now_s) {
  now_s_ = now_s;
  transport_.poll(now_s, 0.0);
  clock_.refresh();
  if (state_ == McuState::kIdle || state_ == McuState::kFailed) return;
  if (state_ == McuState::kDisconnected) {
    // open() every reconnect_period_s; a transport with an I/O thread reopens in the background
    // and is taken as soon as it is up.
    if (!transport_.connected()) {
      if (now_s < next_reconnect_s_) return;
      next_reconnect_s_ = now_s + p_.reconnect_period_s;
      if (!transport_.open().ok()) return;
    }
    state_ = state_before_disconnect_;
    events_.push_back("MCU '" + p_.name + "' (" + transport_.describe() + ") reconnected");
    link_.retransmit_now(ns(now_s));
  }
  if (!transport_.connected()) {
    mark_disconnected(transport_.error_text());
    return;
  }
  uint8_t buf[4096];
  for (int chunks = 0; chunks < 1024; ++chunks) {  // bounded: the I/O thread may keep adding
    Result<size_t> r = transport_.read(buf, sizeof buf);
    if (!r.ok()) {
      mark_disconnected(r.error().message);
      return;
    }
    if (*r == 0) break;
    // When these bytes arrived: the I/O thread's stamp when there is one (on our time line: not
    // after now, not absurdly old), else now.
    const double t = transport_.last_read_time_s();
    rx_time_s_ = t <= now_s && t > now_s - 60.0 ? t : now_s;
    link_.on_bytes(buf, *r, ns(now_s));
    if (state_ == McuState::kFailed) return;
  }
  link_.poll(ns(now_s));
  if (p_.link_stall_s > 0 && link_.in_flight() > 0 && ns(now_s) - link_.last_progress_ns() > ns(p_.link_stall_s)) {
    const std::string silent = std::to_string(static_cast<int>(p_.link_stall_s * 1000.0)) + " ms with " +
                               std::to_string(link_.in_flight()) + " frame(s) in flight";
    const std::string note = io_stall_note();
    if (now_s - last_refused_s_ < p_.link_stall_s)
      fail("MCU '" + p_.name + "' (" + transport_.describe() + ") acknowledged nothing for " + silent +
           " while the transport's send queue refused frames (" + std::to_string(frames_refused_) +
           " so far): its I/O thread is stalled or the device does not read" + note + "; motion stopped");
    else if (state_ == McuState::kIdentifying)
      fail("MCU '" + p_.name + "' (" + transport_.describe() + ") does not answer (nothing acknowledged for " +
           silent + "): is feedloop firmware running there, at this port/device?" + note);
    else
      fail("MCU '" + p_.name + "' (" + transport_.describe() + ") acknowledged nothing for " + silent +
           ": it restarted (and lost its step queue) or hangs" + note +
           "; motion stopped, start the session again to re-identify it");
    return;
  }
  if (state_ == McuState::kReady && now_s >= next_query_s_ && link_.can_send()) {
    send_clock_query();
    next_query_s_ = now_s + (burst_left_ > 0 ? 0.01 : p_.clock_query_period_s);
    if (burst_left_ > 0) --burst_left_;
  }
  while (out_count_ > 0 && link_.can_send()) {
    const OutMsg& m = outbox_[static_cast<size_t>(out_head_)];
    link_.send(m.bytes, m.n, ns(now_s));
    out_head_ = (out_head_ + 1) % kOutboxMessages;
    --out_count_;
  }
  if (state_ == McuState::kReady && now_s - last_send_s_ >= p_.heartbeat_period_s && link_.can_send()) {
    const uint8_t hb = static_cast<uint8_t>(MsgType::kHeartbeat);
    link_.send(&hb, 1, ns(now_s));
  }
}

void McuSession::on_payload(const uint8_t* p, size_t n) {
  MsgReader r(p, n);
  const auto type = static_cast<MsgType>(r.u8());
  switch (type) {
    case MsgType::kIdentifyResponse: {
      const uint16_t version = r.u16();
      const uint64_t hz = r.var();
      const uint8_t axis_byte = r.u8();  // the axis, or 0x80 | motor count for a board
      const int motors = (axis_byte & 0x80) ? (axis_byte & 0x7F) : 1;
      const size_t name_len = r.u8();
      const uint8_t* name = r.take(name_len);
      if (!r.ok()) {
        fail("MCU '" + p_.name + "': malformed identify response");
        return;
      }
      if (version != identify_version_ && version >= protocol::kMinProtocolVersion &&
          version < identify_version_) {
        // An older device that does not speak our version: identify again with its version
        // (its version-mismatch report for our first IDENTIFY is expected and ignored).
        identify_version_ = version;
        const uint8_t m[3] = {static_cast<uint8_t>(MsgType::kIdentify), static_cast<uint8_t>(version & 0xFF),
                              static_cast<uint8_t>(version >> 8)};
        enqueue(m, sizeof m, /*front=*/true);
        return;
      }
      if (version != identify_version_) {
        fail("MCU '" + p_.name + "' (" + transport_.describe() + ", firmware '" +
             std::string(reinterpret_cast<const char*>(name), name_len) + "') speaks protocol version " +
             std::to_string(version) + " but this host speaks version " + std::to_string(p_.protocol_version) +
             ": flash firmware that matches this host (or run the matching host)");
        return;
      }
      // A rate of 0 would make every clock conversion divide by zero; the host keeps 32 bits.
      if (hz == 0 || hz > UINT32_MAX) {
        fail("MCU '" + p_.name + "' (" + transport_.describe() +
             "): its identify response reports a clock of " + std::to_string(hz) +
             " Hz (expected 1 to 4294967295 Hz)");
        return;
      }
      if (motors < 1 || motors > device::VirtualMcu::kMaxAxes) {
        fail("MCU '" + p_.name + "' (" + transport_.describe() +
             "): its identify response reports " + std::to_string(motors) +
             " motors (expected 1 to " + std::to_string(device::VirtualMcu::kMaxAxes) + ")");
        return;
      }
      mcu_axes_ = motors;
      negotiated_version_ = version;
      mcu_clock_hz_ = static_cast<uint32_t>(hz);
      ClockSyncParams cp;
      cp.nominal_hz = static_cast<double>(hz);
      clock_.configure(cp);
      uint8_t buf[40];
      MsgWriter w(buf, sizeof buf);
      w.u8(static_cast<uint8_t>(MsgType::kConfigure))
          .var(static_cast<uint64_t>(std::llround(p_.encoder_period_s * static_cast<double>(hz))))
          .var(static_cast<uint64_t>(p_.samples_per_report))
          .var(static_cast<uint64_t>(std::llround(p_.watchdog_s * static_cast<double>(hz))));
      enqueue(buf, w.size(), /*front=*/true);
      state_ = McuState::kReady;
      burst_left_ = p_.clock_query_burst;
      next_query_s_ = now_s_;
      return;
    }
    case MsgType::kClockResponse: {
      const uint64_t token = r.var();
      const int64_t clock = static_cast<int64_t>(r.var());
      if (!r.ok()) return;
      if (clock < 0) {  // beyond 2^63 ticks: no clock (the clock sync subtracts clocks)
        events_.push_back("MCU '" + p_.name + "': clock response with an impossible clock ignored");
        return;
      }
      for (int i = 0; i < query_count_; ++i) {
        Query& q = queries_[static_cast<size_t>((query_head_ + i) % kMaxQueries)];
        if (q.token != token) continue;
        // The round trip of the wire: from the frame's departure (the I/O thread's stamp; else
        // when it was queued) to the arrival of the reply's bytes.
        const double departed = q.has_ticket ? transport_.departure_time_s(q.ticket) : NAN;
        const double send_s = departed >= q.sent_s && departed <= rx_time_s_ ? departed : q.sent_s;
        clock_.add_sample(send_s, rx_time_s_, clock);
        // Forget it and every older query (their replies are lost or will never match).
        query_head_ = (query_head_ + i + 1) % kMaxQueries;
        query_count_ -= i + 1;
        break;
      }
      return;
    }
    case MsgType::kStatus: {
      DeviceStatus& s = status_scratch_;  // reused: no allocation per status reply
      s.axes.clear();
      s.clock = static_cast<int64_t>(r.var());
      const uint8_t flags = r.u8();
      const int motors = r.u8();
      for (int i = 0; i < motors && r.ok(); ++i) {
        AxisDeviceStatus a;
        a.steps_executed = r.var();
        a.position_steps = r.zz();
        a.queued_runs = r.var();
        a.step_hash = r.var();
        s.axes.push_back(a);
      }
      if (!r.ok() || s.axes.empty()) return;
      s.enabled = flags & protocol::kStatusEnabled;
      s.stopped = flags & protocol::kStatusStopped;
      s.steps_executed = s.axes[0].steps_executed;
      s.position_steps = s.axes[0].position_steps;
      s.queued_runs = s.axes[0].queued_runs;
      s.step_hash = s.axes[0].step_hash;
      if (status_) *status_ = s; else status_ = s;
      // A backstop for a stop whose error report this side did not act on: a stopped MCU takes
      // no steps until it is identified again.
      if (s.stopped && state_ == McuState::kReady)
        fail(
            "MCU '" + p_.name + "' (" + transport_.describe() +
            ") reports in its status that it is stopped; it takes no steps until identified again");
      return;
    }
    case MsgType::kLoopReport: {
      protocol::LoopReportMsg m;
      if (!protocol::decode_loop_report(p, n, m)) {
        events_.push_back("MCU '" + p_.name + "': malformed loop report");
        return;
      }
      if (report_count_ == kLoopMessages) {  // nobody takes them: keep the newest
        report_head_ = (report_head_ + 1) % kLoopMessages;
        --report_count_;
        ++loop_dropped_;
      }
      loop_reports_[(report_head_ + report_count_++) % kLoopMessages] = m;
      return;
    }
    case MsgType::kLoopEvent: {
      protocol::LoopEventMsg m;
      if (!protocol::decode_loop_event(p, n, m)) {
        events_.push_back("MCU '" + p_.name + "': malformed loop event");
        return;
      }
      if (event_count_ == kLoopMessages) {
        event_head_ = (event_head_ + 1) % kLoopMessages;
        --event_count_;
        ++loop_dropped_;
      }
      loop_events_[(event_head_ + event_count_++) % kLoopMessages] = m;
      return;
    }
    case MsgType::kEndstopTrigger: {
      protocol::EndstopTriggerMsg m;
      if (!protocol::decode_endstop_trigger(p, n, m)) {
        events_.push_back("MCU '" + p_.name + "': malformed endstop trigger");
        return;
      }
      put_ring(es_triggers_, es_trigger_head_, es_trigger_count_, m);
      return;
    }
    case MsgType::kEndstopState: {
      protocol::EndstopStateMsg m;
      if (!protocol::decode_endstop_state(p, n, m)) {
        events_.push_back("MCU '" + p_.name + "': malformed endstop state");
        return;
      }
      put_ring(es_states_, es_state_head_, es_state_count_, m);
      return;
    }
    case MsgType::kHeaterReport:
    case MsgType::kHeaterFault: {
      protocol::HeaterReportMsg rep;
      protocol::HeaterFaultMsg flt;
      const bool ok = type == MsgType::kHeaterReport ? protocol::decode_heater_report(p, n, rep)
                                                     : protocol::decode_heater_fault(p, n, flt);
      if (!ok || n > sizeof(HeaterPayload::bytes)) {
        events_.push_back("MCU '" + p_.name + "': malformed heater message ignored");
        return;
      }
      HeaterPayload h;
      h.n = static_cast<uint8_t>(n);
      std::memcpy(h.bytes, p, n);
      put_ring(heater_msgs_, heater_head_, heater_count_, h);
      return;
    }
    case MsgType::kEncoderReport: {
      const int axis = r.u8();
      const int64_t first = static_cast<int64_t>(r.var());
      const int64_t period = static_cast<int64_t>(r.var());
      const uint64_t count = r.var();
      // Checked in full before any sample is kept: every clock and count must fit 64 bits.
      const MsgReader deltas = r;
      int64_t counts = r.zz();
      bool valid = r.ok() && first >= 0 && period >= 0 && count <= n;  // a sample takes >= 1 byte
      for (uint64_t i = 1; valid && i < count; ++i) {
        const int64_t d = r.zz();
        int64_t clock = 0;
        valid = r.ok() && !__builtin_add_overflow(counts, d, &counts) &&
                !__builtin_mul_overflow(static_cast<int64_t>(i), period, &clock) &&
                !__builtin_add_overflow(first, clock, &clock);
      }
      if (!valid) {
        events_.push_back("MCU '" + p_.name + "': malformed encoder report (" + std::to_string(n) +
                          " bytes) ignored");
        return;
      }
      r = deltas;
      counts = r.zz();
      for (uint64_t i = 0; i < count; ++i) {
        if (i > 0) counts += r.zz();
        if (samples_.size() >= kSampleCapacity) {
          ++samples_dropped_;
          continue;
        }
        samples_.push_back({axis, first + static_cast<int64_t>(i) * period, counts});
      }
      return;
    }
    case MsgType::kErrorReport: {
      const auto code = static_cast<McuError>(r.u8());
      const int64_t clock = static_cast<int64_t>(r.var());
      const int64_t detail = r.zz();
      std::string msg = "MCU '" + p_.name + "' (" + transport_.describe() + ") reports " +
                        protocol::mcu_error_name(code) + " at clock " + std::to_string(clock) +
                        " (detail " + std::to_string(detail) + ")";
      if (code == McuError::kVersionMismatch && identify_version_ != p_.protocol_version &&
          detail == identify_version_) {
        return;  // the reply to our first IDENTIFY before we fell back to the device's version
      }
      if (code == McuError::kVersionMismatch) {
        fail(msg + ": device speaks protocol version " + std::to_string(detail) + ", host speaks " +
             std::to_string(p_.protocol_version));
      } else if (code == McuError::kQueueUnderrun || code == McuError::kWatchdog ||
                 code == McuError::kEmergencyStop || code == McuError::kBatchOverlap ||
                 code == McuError::kQueueOverflow || code == McuError::kFollowingError ||
                 code == McuError::kEncoderFault || code == McuError::kTargetUnderrun ||
                 code == McuError::kTargetOverflow) {
        // kTargetOverflow: r(t) lost a knot, so the device loop brakes to rest and the MCU stops
        // (it was an event only: the host streamed on to an MCU that no longer took its steps).
        fail(msg + io_stall_note() + "; the MCU stopped its motor");
      } else if (code == McuError::kBadLoopConfig) {
        // The device loop the host configured is not running as configured (the set is refused
        // whole: docs/protocol.md). Going on would print with the loop off, or on the old
        // parameters, while the host believes it closed: it was an event only until 2026-12-06.
        const auto why =
            static_cast<device::LoopParamError>(detail >= 0 && detail < 256 ? detail : 255);
        fail(msg + ": " + device::loop_param_error_name(why) +
             "; the device loop is not running as configured, motion stopped");
      } else if (code == McuError::kNotIdentified && state_ == McuState::kReady) {
        // An identified MCU never says this: it restarted or stopped, and every step sent since
        // is lost.
        fail(msg + ": the MCU no longer knows this session (it restarted or stopped)");
      } else {
        events_.push_back(std::move(msg));
      }
      return;
    }
    default:
      events_.push_back("MCU '" + p_.name + "': unexpected message type " + std::to_string(static_cast<int>(type)));
      return;
  }
}

}  // namespace feedloop::drivers
