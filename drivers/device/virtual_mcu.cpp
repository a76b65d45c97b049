// Virtual MCU: see virtual_mcu.hpp. No heap, no exceptions, no standard library containers.
#include "drivers/device/virtual_mcu.hpp"

#include <chrono>   // steady_clock (the loop tick's cost in LOOP_REPORT)
#include <cmath>    // floor
#include <cstring>  // memcpy

#include "drivers/device/heater_board.hpp"
#include "drivers/protocol/endstop_messages.hpp"
#include "drivers/protocol/loop_messages.hpp"
#include "drivers/stepgen/run_codec.hpp"

namespace feedloop::device {

using protocol::McuError;
using protocol::MsgReader;
using protocol::MsgType;
using protocol::MsgWriter;

namespace {
constexpr int64_t kNever = INT64_MAX;
}

VirtualMcu::VirtualMcu(const VirtualMcuParams& params, MotorPort* port) : VirtualMcu(params, &port, 1) {}

VirtualMcu::VirtualMcu(const VirtualMcuParams& params, MotorPort* const* ports, int num_axes,
                       HeaterBoard* heaters)
    : params_(params), rate_hz_(params.clock_hz * (1.0 + params.drift_ppm * 1e-6)), heaters_(heaters) {
  link_.configure(params_.link, this, this);
  num_axes_ = num_axes < 1 ? 1 : (num_axes > kMaxAxes ? kMaxAxes : num_axes);
  for (int i = 0; i < num_axes_; ++i) {
    axes_[i].port = ports[i];
    axes_[i].st.step_hash = kStepHashSeed;
    axes_[i].loop.init(static_cast<float>(params_.clock_hz));
  }
  status_.num_axes = num_axes_;
  sync_status();
}

void VirtualMcu::sync_status() {
  for (int i = 0; i < num_axes_; ++i) {
    axes_[i].st.queued_runs = static_cast<uint32_t>(axes_[i].run_count);
    status_.axes[i] = axes_[i].st;
  }
  const AxisStatus& a0 = axes_[0].st;
  status_.steps_executed = a0.steps_executed;
  status_.position_steps = a0.position_steps;
  status_.step_hash = a0.step_hash;
  status_.queued_runs = a0.queued_runs;
}

int64_t VirtualMcu::clock_at(double t_s) const {
  return static_cast<int64_t>(std::floor((t_s + params_.offset_s) * rate_hz_));
}

double VirtualMcu::true_time_at(int64_t clock) const {
  return static_cast<double>(clock) / rate_hz_ - params_.offset_s;
}

int64_t VirtualMcu::now_ns() const {
  return static_cast<int64_t>(static_cast<double>(now_clock_) * (1e9 / params_.clock_hz));
}

void VirtualMcu::write_frame(const uint8_t* frame, size_t n) {
  if (out_count_ == kMaxOutFrames) {
    ++status_.frames_dropped;  // the link retransmits data frames; acks are repeated anyway
    return;
  }
  const int idx = (out_head_ + out_count_) % kMaxOutFrames;
  std::memcpy(out_frames_[idx], frame, n);
  out_len_[idx] = n;
  ++out_count_;
}

bool VirtualMcu::pop_frame(uint8_t* out, size_t& n) {
  if (out_count_ == 0) return false;
  n = out_len_[out_head_];
  std::memcpy(out, out_frames_[out_head_], n);
  out_head_ = (out_head_ + 1) % kMaxOutFrames;
  --out_count_;
  return true;
}

void VirtualMcu::send_msg(const uint8_t* p, size_t n, bool droppable) {
  if (pending_count_ == 0 && link_.send(p, n, now_ns())) return;
  if (pending_count_ == kMaxPending || (droppable && pending_count_ >= kMaxPending / 2)) {
    ++status_.reports_dropped;
    return;
  }
  const int idx = (pending_head_ + pending_count_) % kMaxPending;
  std::memcpy(pending_[idx], p, n);
  pending_len_[idx] = n;
  ++pending_count_;
}

void VirtualMcu::flush_pending() {
  while (pending_count_ > 0 && link_.can_send()) {
    link_.send(pending_[pending_head_], pending_len_[pending_head_], now_ns());
    pending_head_ = (pending_head_ + 1) % kMaxPending;
    --pending_count_;
  }
}

void VirtualMcu::send_error(McuError code, int64_t detail) {
  uint8_t buf[32];
  MsgWriter w(buf, sizeof buf);
  w.u8(static_cast<uint8_t>(MsgType::kErrorReport)).u8(static_cast<uint8_t>(code)).var(static_cast<uint64_t>(now_clock_)).zz(detail);
  status_.last_error = code;
  ++status_.errors;
  send_msg(buf, w.size());
}

void VirtualMcu::send_status() {
  uint8_t buf[8 + kMaxAxes * 40];
  MsgWriter w(buf, sizeof buf);
  const uint8_t flags = static_cast<uint8_t>((status_.enabled ? protocol::kStatusEnabled : 0) |
                                             (status_.stopped ? protocol::kStatusStopped : 0));
  w.u8(static_cast<uint8_t>(MsgType::kStatus)).var(static_cast<uint64_t>(now_clock_)).u8(flags).u8(static_cast<uint8_t>(num_axes_));
  for (int i = 0; i < num_axes_; ++i) {
    const Axis& a = axes_[i];
    w.var(a.st.steps_executed).zz(a.st.position_steps).var(static_cast<uint64_t>(a.run_count)).var(a.st.step_hash);
  }
  send_msg(buf, w.size());
}

void VirtualMcu::send_encoder_report(int axis) {
  if (nsamples_ == 0) return;
  const Axis& a = axes_[axis];
  uint8_t buf[protocol::kMaxPayload];
  MsgWriter w(buf, sizeof buf);
  w.u8(static_cast<uint8_t>(MsgType::kEncoderReport))
      .u8(static_cast<uint8_t>(axis))
      .var(static_cast<uint64_t>(a.sample_first_clock))
      .var(static_cast<uint64_t>(encoder_period_ticks_))
      .var(static_cast<uint64_t>(nsamples_))
      .zz(a.samples[0]);
  for (int i = 1; i < nsamples_; ++i) w.zz(a.samples[i] - a.samples[i - 1]);
  if (!w.ok()) {
    ++status_.reports_dropped;
    return;
  }
  send_msg(buf, w.size(), true);
}

void VirtualMcu::stop(McuError code, int64_t detail) {
  for (int i = 0; i < num_axes_; ++i) {
    Axis& a = axes_[i];
    a.run_head = a.run_count = 0;
    a.have_queued_end = false;
    a.extra_left = 0;
    a.es_armed = a.es_triggered = false;
    a.loop.init(static_cast<float>(params_.clock_hz));
    if (status_.enabled && a.port != nullptr) a.port->set_enabled(true_time_at(now_clock_), false);
  }
  loop_stopping_ = false;
  // A stopped MCU drives nothing: its heaters go off too (Klipper's MCU shutdown), and SET_HEATER
  // is refused until the host identifies it again.
  if (heaters_ != nullptr) heaters_->all_off(now_clock_);
  status_.enabled = false;
  status_.stopped = true;
  sync_status();
  status_.stop_reason = code;
  send_error(code, detail);
}

void VirtualMcu::activate_head(Axis& a) {
  const QueuedRun& q = a.runs[a.run_head];
  a.last_step_clock = q.start_clock;
  a.interval = q.run.interval_ticks;
  a.next_step_clock = a.last_step_clock + a.interval;
  a.run_k = 0;
}

void VirtualMcu::do_step(Axis& a) {
  const QueuedRun& q = a.runs[a.run_head];
  const int dir = q.run.direction;
  if (a.port != nullptr) a.port->step(true_time_at(a.next_step_clock), dir);
  a.st.position_steps += dir;
  ++a.st.steps_executed;
  a.st.step_hash = step_hash_update(a.st.step_hash, a.next_step_clock, dir);
  a.last_step_clock = a.next_step_clock;
  a.interval += q.run.add_ticks;
  if (++a.run_k == q.run.count) {
    a.run_head = (a.run_head + 1) % kMaxRuns;
    --a.run_count;
    if (a.run_count > 0) activate_head(a);
  } else {
    a.next_step_clock = a.last_step_clock + a.interval;
  }
}

double VirtualMcu::next_event_time() const {
  int64_t e = kNever;
  for (int i = 0; i < num_axes_; ++i) {
    const Axis& a = axes_[i];
    if (a.run_count > 0 && a.next_step_clock < e) e = a.next_step_clock;
    if (a.extra_left != 0 && a.extra_next_clock < e) e = a.extra_next_clock;
    if (a.loop.next_tick_clock() < e) e = a.loop.next_tick_clock();
    if (a.es_armed && !a.es_triggered && a.es_next_clock < e) e = a.es_next_clock;
  }
  if (encoder_period_ticks_ > 0 && next_sample_clock_ < e) e = next_sample_clock_;
  if (heaters_ != nullptr && heaters_->next_event_clock() < e) e = heaters_->next_event_clock();
  if (status_.enabled && watchdog_ticks_ > 0 && !loop_stopping_ && last_host_clock_ + watchdog_ticks_ < e)
    e = last_host_clock_ + watchdog_ticks_;
  if (link_.in_flight() > 0) {
    const int64_t soon = now_clock_ + static_cast<int64_t>(params_.clock_hz * 0.005);
    if (soon < e) e = soon;
  }
  return e == kNever ? 1e300 : true_time_at(e);
}

void VirtualMcu::run_until(double t_s) {
  const int64_t target = clock_at(t_s);
  for (;;) {
    // In clock order; at equal clocks: the host's steps, the loop's steps, encoder samples, loop
    // ticks (which then see every step due at their instant), the watchdog.
    int64_t e = kNever;
    int what = 0;
    int axis = 0;
    for (int i = 0; i < num_axes_; ++i)
      if (axes_[i].run_count > 0 && axes_[i].next_step_clock < e) {
        e = axes_[i].next_step_clock;
        what = 1;
        axis = i;
      }
    for (int i = 0; i < num_axes_; ++i)
      if (axes_[i].extra_left != 0 && axes_[i].extra_next_clock < e) {
        e = axes_[i].extra_next_clock;
        what = 5;
        axis = i;
      }
    if (encoder_period_ticks_ > 0 && next_sample_clock_ < e) { e = next_sample_clock_; what = 2; }
    for (int i = 0; i < num_axes_; ++i)
      if (axes_[i].loop.next_tick_clock() < e) {
        e = axes_[i].loop.next_tick_clock();
        what = 4;
        axis = i;
      }
    for (int i = 0; i < num_axes_; ++i)
      if (axes_[i].es_armed && !axes_[i].es_triggered && axes_[i].es_next_clock < e) {
        e = axes_[i].es_next_clock;
        what = 6;
        axis = i;
      }
    if (status_.enabled && watchdog_ticks_ > 0 && !loop_stopping_ && last_host_clock_ + watchdog_ticks_ < e) {
      e = last_host_clock_ + watchdog_ticks_;
      what = 3;
    }
    if (heaters_ != nullptr && heaters_->next_event_clock() < e) {
      e = heaters_->next_event_clock();
      what = 7;
    }
    if (e > target) break;
    if (e > now_clock_) now_clock_ = e;
    if (what == 1) {
      do_step(axes_[axis]);
    } else if (what == 5) {
      do_extra_step(axes_[axis]);
    } else if (what == 4) {
      loop_tick(axis);
    } else if (what == 6) {
      endstop_sample(axis);
    } else if (what == 7) {
      heaters_->run(now_clock_);  // samples, the MCU's own limits, the 3 s re-confirm rule
      send_heater_messages();
    } else if (what == 2) {
      for (int i = 0; i < num_axes_; ++i) {
        Axis& a = axes_[i];
        if (nsamples_ == 0) a.sample_first_clock = next_sample_clock_;
        a.samples[nsamples_] = a.port != nullptr ? a.port->read_encoder_counts(true_time_at(next_sample_clock_)) : 0;
      }
      ++nsamples_;
      next_sample_clock_ += encoder_period_ticks_;
      if (nsamples_ >= samples_per_report_) {
        for (int i = 0; i < num_axes_; ++i) send_encoder_report(i);
        nsamples_ = 0;
      }
    } else {
      bool any_loop = false;
      for (int i = 0; i < num_axes_; ++i) any_loop = any_loop || axes_[i].loop.state() == LoopState::kRunning;
      if (any_loop) {
        begin_controlled_stop(StopReason::kHostSilent, McuError::kWatchdog, now_clock_ - last_host_clock_);
      } else {
        stop(McuError::kWatchdog, now_clock_ - last_host_clock_);
      }
    }
  }
  if (target > now_clock_) now_clock_ = target;
  sync_status();
  flush_pending();
  link_.poll(now_ns());
}

void VirtualMcu::receive(const uint8_t* data, size_t n, double t_s) {
  run_until(t_s);
  link_.on_bytes(data, n, now_ns());
  flush_pending();
}

void VirtualMcu::do_extra_step(Axis& a) {
  const int dir = a.extra_left > 0 ? 1 : -1;
  if (a.port != nullptr) a.port->device_step(true_time_at(a.extra_next_clock), dir);
  a.st.device_steps += dir;
  ++a.st.device_steps_executed;
  a.extra_left -= dir;
  ++a.extra_k;
  // Step k of n at start + (k + 1/2) span / n: evenly spread, the last one before the next tick.
  a.extra_next_clock = a.extra_start + ((2 * static_cast<int64_t>(a.extra_k) + 1) * a.extra_span) / (2 * a.extra_n);
}

void VirtualMcu::send_loop_events(int axis) {
  LoopEvent ev;
  while (axes_[axis].loop.pop_event(ev)) {
    uint8_t buf[48];
    const size_t n = protocol::encode_loop_event({static_cast<uint8_t>(axis), ev}, buf, sizeof buf);
    if (n > 0) send_msg(buf, n);
  }
}

void VirtualMcu::begin_controlled_stop(StopReason why, McuError code, int64_t detail) {
  if (loop_stopping_) return;
  loop_stopping_ = true;
  stop_code_ = code;
  stop_detail_ = detail;
  bool any = false;
  for (int i = 0; i < num_axes_; ++i) {
    Axis& a = axes_[i];
    if (a.loop.state() == LoopState::kRunning) {
      a.loop.request_stop(why);
      any = true;
    } else if (a.loop.state() == LoopState::kStopping) {
      any = true;  // the axis that tripped: already braking
    } else {
      a.run_head = a.run_count = 0;  // no loop on this motor: it stops at once, as in protocol v1
      a.have_queued_end = false;
    }
  }
  if (!any) stop(code, detail);
}

void VirtualMcu::loop_tick(int axis) {
  Axis& a = axes_[axis];
  LoopTickIn in;
  in.clock = now_clock_;
  in.encoder_counts = a.port != nullptr ? a.port->read_encoder_counts(true_time_at(now_clock_)) : 0;
  in.motor_steps = a.st.position_steps + a.st.device_steps;
  in.device_steps = a.st.device_steps;
  LoopTickOut out;
  if (params_.measure_tick_cost) {
    const auto t0 = std::chrono::steady_clock::now();
    a.loop.tick(in, out);
    const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0).count();
    a.loop.note_tick_cost(static_cast<uint32_t>(ns));
  } else {
    a.loop.tick(in, out);
  }
  if (out.step_fraction != a.step_fraction && a.port != nullptr) {
    a.step_fraction = out.step_fraction;
    a.port->set_step_fraction(true_time_at(now_clock_), out.step_fraction);
  }
  a.extra_left = out.extra_steps;
  if (out.extra_steps != 0) {
    a.extra_n = out.extra_steps > 0 ? out.extra_steps : -out.extra_steps;
    a.extra_k = 0;
    a.extra_start = now_clock_;
    a.extra_span = out.over_ticks > 0 ? out.over_ticks : 1;
    a.extra_next_clock = a.extra_start + a.extra_span / (2 * a.extra_n);
  }
  if (out.flush_host_steps) {
    a.run_head = a.run_count = 0;
    a.have_queued_end = false;
    const StopReason why = a.loop.stop_reason();
    if (why != StopReason::kPeer && why != StopReason::kHostSilent && why != StopReason::kHost) {
      // This axis tripped: every other axis of the MCU stops too.
      McuError code = McuError::kTargetUnderrun;
      if (why == StopReason::kFollowingError) code = McuError::kFollowingError;
      if (why == StopReason::kEncoderFault) code = McuError::kEncoderFault;
      begin_controlled_stop(StopReason::kPeer, code, axis);
    }
  }
  if (out.report_due) {
    protocol::LoopReportMsg m;
    m.axis = static_cast<uint8_t>(axis);
    a.loop.take_report(m.report);
    uint8_t buf[96];
    const size_t n = protocol::encode_loop_report(m, buf, sizeof buf);
    if (n > 0) send_msg(buf, n, /*droppable=*/true);
  }
  send_loop_events(axis);
  if (out.stopped) {
    bool all = true;
    for (int i = 0; i < num_axes_; ++i) all = all && !(axes_[i].loop.active());
    if (all) stop(stop_code_ == McuError::kNone ? McuError::kTargetUnderrun : stop_code_, stop_detail_);
  }
}

void VirtualMcu::handle_configure_loop(const uint8_t* p, size_t n) {
  protocol::ConfigureLoopMsg m;
  if (negotiated_version_ < 2 || !protocol::decode_configure_loop(p, n, m) || m.axis >= num_axes_) {
    send_error(McuError::kBadMessage, static_cast<int64_t>(MsgType::kConfigureLoop));
    return;
  }
  const LoopParamError err = axes_[m.axis].loop.stage(m.params, m.activation_clock);
  send_loop_events(m.axis);
  if (err != LoopParamError::kOk) send_error(McuError::kBadLoopConfig, static_cast<int64_t>(err));
}

void VirtualMcu::handle_queue_target(const uint8_t* p, size_t n) {
  protocol::QueueTargetReader r;
  if (negotiated_version_ < 2 || !r.begin(p, n) || r.axis() >= num_axes_) {
    send_error(McuError::kBadMessage, static_cast<int64_t>(MsgType::kQueueTarget));
    return;
  }
  Axis& a = axes_[r.axis()];
  TargetKnot k;
  while (r.next(k)) {
    if (!a.loop.push_target(k)) {
      send_loop_events(r.axis());
      send_error(McuError::kTargetOverflow, r.axis());
      if (a.loop.state() == LoopState::kRunning) begin_controlled_stop(StopReason::kHost, McuError::kTargetOverflow, r.axis());
      return;
    }
  }
  if (!r.ok()) send_error(McuError::kBadMessage, static_cast<int64_t>(MsgType::kQueueTarget));
}

void VirtualMcu::handle_queue_steps(MsgReader& r) {
  const int axis = r.u8();
  if (!r.ok() || axis >= num_axes_) {
    send_error(McuError::kBadMessage, static_cast<int64_t>(MsgType::kQueueSteps));
    return;
  }
  Axis& a = axes_[axis];
  size_t n = 0;
  const uint8_t* body = r.rest(n);
  // The whole batch is checked before any of its runs is queued: nothing half-done.
  stepgen::RunDecoder dec;
  if (!dec.begin(body, n) || dec.first_clock() < 0) {  // a clock above INT64_MAX is no clock
    send_error(McuError::kBadMessage, static_cast<int64_t>(MsgType::kQueueSteps));
    return;
  }
  int64_t p = dec.first_clock();
  int64_t first_step = 0;
  int runs = 0;
  while (!dec.done()) {
    stepgen::StepRun run;
    // A run that steps back in time or overflows the clock is as malformed as a truncated one.
    if (!dec.next(run) || !stepgen::run_is_valid(p, run)) {
      send_error(McuError::kBadMessage, static_cast<int64_t>(MsgType::kQueueSteps));
      return;
    }
    if (runs++ == 0) first_step = p + run.interval_ticks;
    p = stepgen::run_end_clock(p, run);
  }
  // After an endstop trigger the motor's steps stay stopped until the host disarms it: the steps
  // it queued before it learnt of the trigger are dropped (Klipper: trsync stops the stepper).
  if (a.es_triggered) return;
  if (a.have_queued_end && dec.first_clock() < a.queued_end_clock) {
    stop(McuError::kBatchOverlap, a.queued_end_clock - dec.first_clock());
    return;
  }
  if (runs > 0 && first_step < now_clock_) {
    stop(McuError::kQueueUnderrun, now_clock_ - first_step);
    return;
  }
  if (a.run_count + runs > kMaxRuns) {
    stop(McuError::kQueueOverflow, axis);
    return;
  }
  dec.begin(body, n);
  p = dec.first_clock();
  while (!dec.done()) {
    stepgen::StepRun run;
    dec.next(run);  // decoded above
    const int idx = (a.run_head + a.run_count) % kMaxRuns;
    a.runs[idx] = {p, run};
    if (++a.run_count == 1) activate_head(a);
    p = stepgen::run_end_clock(p, run);
  }
  a.queued_end_clock = p;
  a.have_queued_end = true;
  sync_status();
}

void VirtualMcu::handle_endstop_home(const uint8_t* p, size_t n) {
  protocol::EndstopHomeMsg m;
  if (!protocol::decode_endstop_home(p, n, m) || m.axis >= num_axes_ || m.sample_count == 0 ||
      (m.flags != 0 && negotiated_version_ < 4)) {
    send_error(McuError::kBadMessage, static_cast<int64_t>(MsgType::kEndstopHome));
    return;
  }
  Axis& a = axes_[m.axis];
  a.es_report_encoder = (m.flags & protocol::kEndstopReportEncoder) != 0;
  a.es_index = m.source == protocol::EndstopSource::kEncoderIndex;
  a.es_stall = m.source == protocol::EndstopSource::kStall && a.port != nullptr;
  if (a.es_stall) {
    a.es_stall_cps_q16 = m.stall_counts_per_step_q16;
    a.es_stall_threshold = m.stall_threshold_counts;
    a.es_stall_steps0 = a.st.position_steps;
    a.es_stall_enc0 = a.port->read_encoder_counts(true_time_at(now_clock_));
  }
  a.es_triggered = false;
  a.es_seen = 0;
  a.es_armed = m.sample_ticks > 0;
  a.es_level = m.trigger_level != 0 ? 1 : 0;
  a.es_count = m.sample_count;
  a.es_ticks = m.sample_ticks;
  a.es_next_clock = now_clock_ + a.es_ticks;
  if (a.es_armed && m.source == protocol::EndstopSource::kNow) {
    // Triggered by the host (another MCU's switch relayed, or a position query at rest): the
    // motor stops where it is now, and the trigger and the stop are both this step position.
    a.es_first_clock = now_clock_;
    a.es_first_steps = a.st.position_steps;
    if (a.es_report_encoder && a.port != nullptr)
      a.es_first_encoder = a.port->read_encoder_counts(true_time_at(now_clock_));
    endstop_trigger(m.axis, now_clock_);
  }
}

void VirtualMcu::handle_endstop_query(const uint8_t* p, size_t n) {
  protocol::EndstopQueryMsg m;
  if (!protocol::decode_endstop_query(p, n, m) || m.axis >= num_axes_) {
    send_error(McuError::kBadMessage, static_cast<int64_t>(MsgType::kEndstopQuery));
    return;
  }
  const Axis& a = axes_[m.axis];
  protocol::EndstopStateMsg s;
  s.axis = m.axis;
  s.pin = a.port != nullptr && a.port->read_endstop(true_time_at(now_clock_)) ? 1 : 0;
  s.armed = a.es_armed ? 1 : 0;
  s.triggered = a.es_triggered ? 1 : 0;
  uint8_t buf[16];
  const size_t len = protocol::encode_endstop_state(s, buf, sizeof buf);
  if (len > 0) send_msg(buf, len);
}

void VirtualMcu::endstop_sample(int axis) {
  Axis& a = axes_[axis];
  const int64_t at = a.es_next_clock;
  a.es_next_clock += a.es_ticks;
  bool pin = false;
  if (a.port != nullptr && a.es_stall) {
    // Steps since arming in counts (16.16, exact in int64 for any travel), less the encoder's.
    const int64_t steps = a.st.position_steps - a.es_stall_steps0;
    const int64_t expected = (steps * a.es_stall_cps_q16) / 65536;
    const int64_t moved = a.port->read_encoder_counts(true_time_at(at)) - a.es_stall_enc0;
    const int64_t lag = expected - moved;
    pin = lag > a.es_stall_threshold || lag < -a.es_stall_threshold;
  } else if (a.port != nullptr) {
    pin = a.es_index ? a.port->read_encoder_index(true_time_at(at))
                     : a.port->read_endstop(true_time_at(at));
  }
  if ((pin ? 1 : 0) != a.es_level) {
    a.es_seen = 0;
    return;
  }
  if (a.es_seen++ == 0) {
    a.es_first_clock = at;
    a.es_first_steps = a.st.position_steps;
    if (a.es_report_encoder && a.port != nullptr)
      a.es_first_encoder = a.port->read_encoder_counts(true_time_at(at));
  }
  if (a.es_seen < a.es_count) return;
  endstop_trigger(axis, at);
}

// Confirmed (or triggered by the host): stop this motor's steps now (its queue is flushed) and
// report the first triggered sample and the stop.
void VirtualMcu::endstop_trigger(int axis, int64_t at) {
  Axis& a = axes_[axis];
  a.run_head = a.run_count = 0;
  a.have_queued_end = false;
  a.es_triggered = true;
  protocol::EndstopTriggerMsg m;
  m.axis = static_cast<uint8_t>(axis);
  m.trigger_clock = a.es_first_clock;
  m.trigger_steps = a.es_first_steps;
  m.stop_clock = at;
  m.stop_steps = a.st.position_steps;
  m.has_encoder = a.es_report_encoder && a.port != nullptr;
  m.trigger_encoder_counts = a.es_first_encoder;
  uint8_t buf[48];
  const size_t len = protocol::encode_endstop_trigger(m, buf, sizeof buf);
  if (len > 0) send_msg(buf, len);
  sync_status();
}

void VirtualMcu::handle_heater_message(uint8_t type, const uint8_t* p, size_t n) {
  // A v1/v2 session does not know them; an MCU without heaters has none to drive.
  if (negotiated_version_ < 3 || heaters_ == nullptr) {
    send_error(McuError::kBadMessage, type);
    return;
  }
  // A stopped MCU keeps its heaters off (SET_HEATER / SET_FAN refused until identified again).
  if (status_.stopped && type != static_cast<uint8_t>(MsgType::kConfigureHeater)) {
    send_error(McuError::kNotIdentified, type);
    return;
  }
  if (!heaters_->on_message(p, n, now_clock_)) send_error(McuError::kBadMessage, type);
  send_heater_messages();  // a refused configuration's HEATER_FAULT
}

void VirtualMcu::send_heater_messages() {
  uint8_t buf[HeaterBoard::kMsgCap];
  size_t n = 0;
  while (heaters_->pop_message(buf, n)) {
    // Reports give way when the queue is half full (the next comes 0.3 s later); faults never.
    const bool report = n > 0 && buf[0] == static_cast<uint8_t>(MsgType::kHeaterReport);
    send_msg(buf, n, report);
  }
}

void VirtualMcu::on_payload(const uint8_t* p, size_t n) {
  MsgReader r(p, n);
  const auto type = static_cast<MsgType>(r.u8());
  last_host_clock_ = now_clock_;
  if (type == MsgType::kIdentify) {
    const uint16_t host_version = r.u16();
    const uint16_t max_v = params_.protocol_version;
    const uint16_t min_v = params_.min_protocol_version != 0 ? params_.min_protocol_version
                           : max_v == protocol::kProtocolVersion ? protocol::kMinProtocolVersion
                                                                 : max_v;
    const bool agreed = r.ok() && host_version >= min_v && host_version <= max_v;
    uint8_t buf[64];
    MsgWriter w(buf, sizeof buf);
    const size_t name_len = ::strnlen(params_.name, sizeof params_.name);
    w.u8(static_cast<uint8_t>(MsgType::kIdentifyResponse))
        .u16(agreed ? host_version : max_v)
        .var(static_cast<uint64_t>(params_.clock_hz))
        .u8(num_axes_ == 1 ? params_.axis : static_cast<uint8_t>(0x80 | num_axes_))
        .u8(static_cast<uint8_t>(name_len))
        .bytes(reinterpret_cast<const uint8_t*>(params_.name), name_len);
    send_msg(buf, w.size());
    status_.identified = agreed;
    negotiated_version_ = agreed ? host_version : 0;
    status_.negotiated_version = negotiated_version_;
    if (!status_.identified) {
      send_error(McuError::kVersionMismatch, params_.protocol_version);
    } else {
      status_.stopped = false;
      for (int i = 0; i < num_axes_; ++i) {  // a new session starts without a loop
        axes_[i].loop.init(static_cast<float>(params_.clock_hz));
        axes_[i].extra_left = 0;
      }
      loop_stopping_ = false;
    }
    return;
  }
  if (!status_.identified) {
    send_error(McuError::kNotIdentified, static_cast<int64_t>(type));
    return;
  }
  switch (type) {
    case MsgType::kConfigure: {
      const int64_t period = static_cast<int64_t>(r.var());
      const int64_t per_report = static_cast<int64_t>(r.var());
      const int64_t watchdog = static_cast<int64_t>(r.var());
      if (!r.ok() || per_report < 1 || per_report > kMaxSamples || period < 0 || watchdog < 0) {
        send_error(McuError::kBadMessage, static_cast<int64_t>(type));
        return;
      }
      encoder_period_ticks_ = period;
      samples_per_report_ = static_cast<int>(per_report);
      watchdog_ticks_ = watchdog;
      nsamples_ = 0;
      next_sample_clock_ = now_clock_ + period;
      return;
    }
    case MsgType::kQueueSteps:
      if (status_.stopped) {
        send_error(McuError::kNotIdentified, static_cast<int64_t>(type));
        return;
      }
      handle_queue_steps(r);
      return;
    case MsgType::kClockQuery: {
      const uint64_t token = r.var();
      uint8_t buf[32];
      MsgWriter w(buf, sizeof buf);
      w.u8(static_cast<uint8_t>(MsgType::kClockResponse)).var(token).var(static_cast<uint64_t>(now_clock_));
      send_msg(buf, w.size());
      return;
    }
    case MsgType::kEnable: {
      const bool on = r.u8() != 0 && !status_.stopped;
      if (on != status_.enabled)
        for (int i = 0; i < num_axes_; ++i)
          if (axes_[i].port != nullptr) axes_[i].port->set_enabled(true_time_at(now_clock_), on);
      status_.enabled = on;
      return;
    }
    case MsgType::kEmergencyStop:
      stop(McuError::kEmergencyStop, 0);
      return;
    case MsgType::kHeartbeat:
      return;
    case MsgType::kConfigureLoop:
      if (status_.stopped) {
        send_error(McuError::kNotIdentified, static_cast<int64_t>(type));
        return;
      }
      handle_configure_loop(p, n);
      return;
    case MsgType::kQueueTarget:
      if (status_.stopped) {
        send_error(McuError::kNotIdentified, static_cast<int64_t>(type));
        return;
      }
      handle_queue_target(p, n);
      return;
    case MsgType::kStatusQuery:
      send_status();
      return;
    case MsgType::kEndstopHome:
    case MsgType::kEndstopQuery:
      if (negotiated_version_ < 3) {  // a v1/v2 session does not know them
        send_error(McuError::kBadMessage, static_cast<int64_t>(type));
        return;
      }
      if (type == MsgType::kEndstopHome) handle_endstop_home(p, n);
      else handle_endstop_query(p, n);
      return;
    case MsgType::kConfigureHeater:
    case MsgType::kSetHeater:
    case MsgType::kSetFan:
      handle_heater_message(static_cast<uint8_t>(type), p, n);
      return;
    default:
      send_error(McuError::kBadMessage, static_cast<int64_t>(type));
      return;
  }
}

}  // namespace feedloop::device
