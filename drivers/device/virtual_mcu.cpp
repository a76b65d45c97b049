// Virtual MCU: see virtual_mcu.hpp. No heap, no exceptions, no standard library containers.
#include "drivers/device/virtual_mcu.hpp"

#include <cmath>    // floor
#include <cstring>  // memcpy

#include "drivers/stepgen/run_codec.hpp"

namespace feedloop::device {

using protocol::McuError;
using protocol::MsgReader;
using protocol::MsgType;
using protocol::MsgWriter;

namespace {
constexpr int64_t kNever = INT64_MAX;
}

VirtualMcu::VirtualMcu(const VirtualMcuParams& params, MotorPort* port)
    : params_(params), port_(port), rate_hz_(params.clock_hz * (1.0 + params.drift_ppm * 1e-6)) {
  link_.configure(params_.link, this, this);
  status_.step_hash = kStepHashSeed;
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
  uint8_t buf[64];
  MsgWriter w(buf, sizeof buf);
  const uint8_t flags = static_cast<uint8_t>((status_.enabled ? protocol::kStatusEnabled : 0) |
                                             (status_.stopped ? protocol::kStatusStopped : 0));
  w.u8(static_cast<uint8_t>(MsgType::kStatus))
      .var(static_cast<uint64_t>(now_clock_))
      .var(status_.steps_executed)
      .zz(status_.position_steps)
      .var(static_cast<uint64_t>(run_count_))
      .var(status_.step_hash)
      .u8(flags);
  send_msg(buf, w.size());
}

void VirtualMcu::send_encoder_report() {
  if (nsamples_ == 0) return;
  uint8_t buf[protocol::kMaxPayload];
  MsgWriter w(buf, sizeof buf);
  w.u8(static_cast<uint8_t>(MsgType::kEncoderReport))
      .var(static_cast<uint64_t>(sample_first_clock_))
      .var(static_cast<uint64_t>(encoder_period_ticks_))
      .var(static_cast<uint64_t>(nsamples_))
      .zz(samples_[0]);
  for (int i = 1; i < nsamples_; ++i) w.zz(samples_[i] - samples_[i - 1]);
  nsamples_ = 0;
  if (!w.ok()) {
    ++status_.reports_dropped;
    return;
  }
  send_msg(buf, w.size(), true);
}

void VirtualMcu::stop(McuError code, int64_t detail) {
  run_head_ = run_count_ = 0;
  have_queued_end_ = false;
  if (status_.enabled && port_ != nullptr) port_->set_enabled(true_time_at(now_clock_), false);
  status_.enabled = false;
  status_.stopped = true;
  status_.queued_runs = 0;
  status_.stop_reason = code;
  send_error(code, detail);
}

void VirtualMcu::activate_head() {
  const QueuedRun& q = runs_[run_head_];
  last_step_clock_ = q.start_clock;
  interval_ = q.run.interval_ticks;
  next_step_clock_ = last_step_clock_ + interval_;
  run_k_ = 0;
}

void VirtualMcu::do_step() {
  const QueuedRun& q = runs_[run_head_];
  const int dir = q.run.direction;
  if (port_ != nullptr) port_->step(true_time_at(next_step_clock_), dir);
  status_.position_steps += dir;
  ++status_.steps_executed;
  status_.step_hash = step_hash_update(status_.step_hash, next_step_clock_, dir);
  last_step_clock_ = next_step_clock_;
  interval_ += q.run.add_ticks;
  if (++run_k_ == q.run.count) {
    run_head_ = (run_head_ + 1) % kMaxRuns;
    --run_count_;
    status_.queued_runs = static_cast<uint32_t>(run_count_);
    if (run_count_ > 0) activate_head();
  } else {
    next_step_clock_ = last_step_clock_ + interval_;
  }
}

double VirtualMcu::next_event_time() const {
  int64_t e = kNever;
  if (run_count_ > 0) e = next_step_clock_;
  if (encoder_period_ticks_ > 0 && next_sample_clock_ < e) e = next_sample_clock_;
  if (status_.enabled && watchdog_ticks_ > 0 && last_host_clock_ + watchdog_ticks_ < e)
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
    int64_t e = kNever;
    int what = 0;
    if (run_count_ > 0) { e = next_step_clock_; what = 1; }
    if (encoder_period_ticks_ > 0 && next_sample_clock_ < e) { e = next_sample_clock_; what = 2; }
    if (status_.enabled && watchdog_ticks_ > 0 && last_host_clock_ + watchdog_ticks_ < e) {
      e = last_host_clock_ + watchdog_ticks_;
      what = 3;
    }
    if (e > target) break;
    if (e > now_clock_) now_clock_ = e;
    if (what == 1) {
      do_step();
    } else if (what == 2) {
      if (nsamples_ == 0) sample_first_clock_ = next_sample_clock_;
      samples_[nsamples_++] = port_ != nullptr ? port_->read_encoder_counts(true_time_at(next_sample_clock_)) : 0;
      next_sample_clock_ += encoder_period_ticks_;
      if (nsamples_ >= samples_per_report_) send_encoder_report();
    } else {
      stop(McuError::kWatchdog, now_clock_ - last_host_clock_);
    }
  }
  if (target > now_clock_) now_clock_ = target;
  flush_pending();
  link_.poll(now_ns());
}

void VirtualMcu::receive(const uint8_t* data, size_t n, double t_s) {
  run_until(t_s);
  link_.on_bytes(data, n, now_ns());
  flush_pending();
}

void VirtualMcu::handle_queue_steps(MsgReader& r) {
  r.u8();  // axis (one MCU per axis: informational)
  size_t n = 0;
  const uint8_t* body = r.rest(n);
  stepgen::RunDecoder dec;
  if (!dec.begin(body, n)) {
    send_error(McuError::kBadMessage, static_cast<int64_t>(MsgType::kQueueSteps));
    return;
  }
  int64_t p = dec.first_clock();
  if (have_queued_end_ && p < queued_end_clock_) {
    stop(McuError::kBatchOverlap, queued_end_clock_ - p);
    return;
  }
  bool first = true;
  while (!dec.done()) {
    stepgen::StepRun run;
    if (!dec.next(run)) {
      send_error(McuError::kBadMessage, static_cast<int64_t>(MsgType::kQueueSteps));
      return;
    }
    if (first) {
      const int64_t first_step = p + run.interval_ticks;
      if (first_step < now_clock_) {
        stop(McuError::kQueueUnderrun, now_clock_ - first_step);
        return;
      }
      first = false;
    }
    if (run_count_ == kMaxRuns) {
      stop(McuError::kQueueOverflow, 1);
      return;
    }
    const int idx = (run_head_ + run_count_) % kMaxRuns;
    runs_[idx] = {p, run};
    if (++run_count_ == 1) activate_head();
    p = stepgen::run_end_clock(p, run);
  }
  queued_end_clock_ = p;
  have_queued_end_ = true;
  status_.queued_runs = static_cast<uint32_t>(run_count_);
}

void VirtualMcu::on_payload(const uint8_t* p, size_t n) {
  MsgReader r(p, n);
  const auto type = static_cast<MsgType>(r.u8());
  last_host_clock_ = now_clock_;
  if (type == MsgType::kIdentify) {
    const uint16_t host_version = r.u16();
    uint8_t buf[64];
    MsgWriter w(buf, sizeof buf);
    const size_t name_len = ::strnlen(params_.name, sizeof params_.name);
    w.u8(static_cast<uint8_t>(MsgType::kIdentifyResponse))
        .u16(params_.protocol_version)
        .var(static_cast<uint64_t>(params_.clock_hz))
        .u8(params_.axis)
        .u8(static_cast<uint8_t>(name_len))
        .bytes(reinterpret_cast<const uint8_t*>(params_.name), name_len);
    send_msg(buf, w.size());
    status_.identified = r.ok() && host_version == params_.protocol_version;
    if (!status_.identified) {
      send_error(McuError::kVersionMismatch, params_.protocol_version);
    } else {
      status_.stopped = false;
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
      if (on != status_.enabled && port_ != nullptr) port_->set_enabled(true_time_at(now_clock_), on);
      status_.enabled = on;
      return;
    }
    case MsgType::kEmergencyStop:
      stop(McuError::kEmergencyStop, 0);
      return;
    case MsgType::kHeartbeat:
      return;
    case MsgType::kStatusQuery:
      send_status();
      return;
    default:
      send_error(McuError::kBadMessage, static_cast<int64_t>(type));
      return;
  }
}

}  // namespace feedloop::device
