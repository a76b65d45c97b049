// Protocol v2 loop messages (see loop_messages.hpp and docs/protocol.md).
#include "drivers/protocol/loop_messages.hpp"

#include "drivers/device/saturate.hpp"

namespace feedloop::protocol {

using device::LoopEventKind;
using device::StopReason;

size_t encode_configure_loop(const ConfigureLoopMsg& m, uint8_t* buf, size_t cap) {
  const device::LoopParams& p = m.params;
  MsgWriter w(buf, cap);
  w.u8(static_cast<uint8_t>(MsgType::kConfigureLoop))
      .u8(m.axis)
      .var(static_cast<uint64_t>(m.activation_clock))
      .u8(static_cast<uint8_t>((p.enabled ? 1 : 0) | (p.deflection_from_host_steps ? 2 : 0) |
                               (p.sub_step_trim ? 4 : 0)))
      .var(p.period_ticks)
      .var(p.nm_per_count_q16)
      .var(p.nm_per_step_q16)
      .f32(p.kp)
      .f32(p.ki_per_s)
      .f32(p.max_correction_nm)
      .f32(p.max_correction_rate_nm_s)
      .f32(p.max_following_error_nm)
      .f32(p.max_speed_nm_s)
      .f32(p.encoder_margin_nm)
      .var(p.encoder_reject_limit)
      .f32(p.slip_threshold_nm)
      .f32(p.slip_cycle_nm)
      .f32(p.slip_settle_s)
      .f32(p.deflection_s2)
      .f32(p.deflection_s)
      .f32(p.accel_filter_s)
      .f32(p.stop_decel_nm_s2)
      .var(p.horizon_margin_ticks)
      .var(p.report_every_ticks)
      .f32(p.reversal_hysteresis_steps);
  return w.ok() ? w.size() : 0;
}

namespace {
uint32_t u32_of(uint64_t v, bool& ok) {
  if (v > 0xFFFFFFFFull) ok = false;
  return static_cast<uint32_t>(v);
}
}  // namespace

bool decode_configure_loop(const uint8_t* buf, size_t n, ConfigureLoopMsg& out) {
  MsgReader r(buf, n);
  if (r.u8() != static_cast<uint8_t>(MsgType::kConfigureLoop)) return false;
  bool ok = true;
  device::LoopParams& p = out.params;
  out.axis = r.u8();
  out.activation_clock = static_cast<int64_t>(r.var());
  const uint8_t flags = r.u8();
  p.enabled = (flags & 1) != 0;
  p.deflection_from_host_steps = (flags & 2) != 0;
  p.sub_step_trim = (flags & 4) != 0;
  p.period_ticks = u32_of(r.var(), ok);
  p.nm_per_count_q16 = u32_of(r.var(), ok);
  p.nm_per_step_q16 = u32_of(r.var(), ok);
  p.kp = r.f32();
  p.ki_per_s = r.f32();
  p.max_correction_nm = r.f32();
  p.max_correction_rate_nm_s = r.f32();
  p.max_following_error_nm = r.f32();
  p.max_speed_nm_s = r.f32();
  p.encoder_margin_nm = r.f32();
  p.encoder_reject_limit = u32_of(r.var(), ok);
  p.slip_threshold_nm = r.f32();
  p.slip_cycle_nm = r.f32();
  p.slip_settle_s = r.f32();
  p.deflection_s2 = r.f32();
  p.deflection_s = r.f32();
  p.accel_filter_s = r.f32();
  p.stop_decel_nm_s2 = r.f32();
  p.horizon_margin_ticks = u32_of(r.var(), ok);
  p.report_every_ticks = u32_of(r.var(), ok);
  // Optional trailing field (added in protocol v2's first revision): absent = plain rounding.
  p.reversal_hysteresis_steps = r.at_end() ? 0.0f : r.f32();
  return ok && r.ok() && r.at_end();
}

size_t encode_queue_target(uint8_t axis, const device::TargetKnot* knots, int count, uint8_t* buf, size_t cap) {
  if (count < 1) return 0;
  MsgWriter w(buf, cap);
  w.u8(static_cast<uint8_t>(MsgType::kQueueTarget))
      .u8(axis)
      .var(static_cast<uint64_t>(count))
      .var(static_cast<uint64_t>(knots[0].clock))
      .zz(knots[0].pos_nm);
  for (int i = 1; i < count; ++i) {
    const int64_t dc = knots[i].clock - knots[i - 1].clock;
    if (dc <= 0) return 0;
    w.var(static_cast<uint64_t>(dc)).zz(knots[i].pos_nm - knots[i - 1].pos_nm);
  }
  return w.ok() ? w.size() : 0;
}

bool QueueTargetReader::begin(const uint8_t* p, size_t n) {
  p_ = p;
  n_ = n;
  pos_ = 0;
  read_ = 0;
  ok_ = false;
  if (n < 1 || p[0] != static_cast<uint8_t>(MsgType::kQueueTarget)) return false;
  pos_ = 1;
  if (pos_ >= n) return false;
  axis_ = p[pos_++];
  uint64_t c = 0;
  if (!get_varint(p, n, pos_, c) || c < 1 || c > 0x7FFFFFFF) return false;
  count_ = static_cast<int>(c);
  ok_ = true;
  return true;
}

bool QueueTargetReader::next(device::TargetKnot& k) {
  if (!ok_ || read_ == count_) {
    if (ok_ && pos_ != n_) ok_ = false;  // trailing bytes
    return false;
  }
  uint64_t a = 0, b = 0;
  if (!get_varint(p_, n_, pos_, a) || !get_varint(p_, n_, pos_, b)) {
    ok_ = false;
    return false;
  }
  // Clocks and positions must fit int64 (and clocks be >= 0): anything else is malformed.
  if (a > static_cast<uint64_t>(INT64_MAX)) {
    ok_ = false;
    return false;
  }
  if (read_ == 0) {
    k.clock = static_cast<int64_t>(a);
    k.pos_nm = unzigzag(b);
  } else if (a == 0 || __builtin_add_overflow(last_.clock, static_cast<int64_t>(a), &k.clock) ||
             __builtin_add_overflow(last_.pos_nm, unzigzag(b), &k.pos_nm)) {
    ok_ = false;
    return false;
  }
  last_ = k;
  ++read_;
  return true;
}

size_t encode_loop_report(const LoopReportMsg& m, uint8_t* buf, size_t cap) {
  const device::LoopReport& r = m.report;
  MsgWriter w(buf, cap);
  w.u8(static_cast<uint8_t>(MsgType::kLoopReport))
      .u8(m.axis)
      .var(static_cast<uint64_t>(r.clock))
      .u8(static_cast<uint8_t>(r.state))
      .zz(r.r_nm)
      .zz(r.y_nm)
      .zz(device::saturate_i64(r.e_nm))  // saturated: NaN -> 0, beyond 2^63 -> the bounds
      .zz(device::saturate_i64(r.u_nm))
      .zz(r.device_steps)
      .var(r.max_tick_cost)
      .var(r.ticks)
      .var(r.deadline_misses)
      .var(r.encoder_rejects)
      .var(r.slips);
  return w.ok() ? w.size() : 0;
}

bool decode_loop_report(const uint8_t* buf, size_t n, LoopReportMsg& out) {
  MsgReader r(buf, n);
  if (r.u8() != static_cast<uint8_t>(MsgType::kLoopReport)) return false;
  device::LoopReport& t = out.report;
  out.axis = r.u8();
  t.clock = static_cast<int64_t>(r.var());
  const uint8_t st = r.u8();
  if (st > static_cast<uint8_t>(device::LoopState::kStopped)) return false;
  t.state = static_cast<device::LoopState>(st);
  t.r_nm = r.zz();
  t.y_nm = r.zz();
  t.e_nm = static_cast<float>(r.zz());
  t.u_nm = static_cast<float>(r.zz());
  t.device_steps = r.zz();
  const uint64_t cost = r.var();
  t.max_tick_cost = cost > 0xFFFFFFFFull ? 0xFFFFFFFFu : static_cast<uint32_t>(cost);
  t.ticks = r.var();
  t.deadline_misses = r.var();
  t.encoder_rejects = r.var();
  t.slips = r.var();
  return r.ok() && r.at_end();
}

size_t encode_loop_event(const LoopEventMsg& m, uint8_t* buf, size_t cap) {
  MsgWriter w(buf, cap);
  w.u8(static_cast<uint8_t>(MsgType::kLoopEvent))
      .u8(m.axis)
      .u8(static_cast<uint8_t>(m.event.kind))
      .var(static_cast<uint64_t>(m.event.clock))
      .zz(m.event.a)
      .zz(m.event.b);
  return w.ok() ? w.size() : 0;
}

bool decode_loop_event(const uint8_t* buf, size_t n, LoopEventMsg& out) {
  MsgReader r(buf, n);
  if (r.u8() != static_cast<uint8_t>(MsgType::kLoopEvent)) return false;
  out.axis = r.u8();
  const uint8_t k = r.u8();
  if (k < 1 || k > static_cast<uint8_t>(LoopEventKind::kTargetRejected)) return false;
  out.event.kind = static_cast<LoopEventKind>(k);
  out.event.clock = static_cast<int64_t>(r.var());
  out.event.a = r.zz();
  out.event.b = r.zz();
  return r.ok() && r.at_end();
}

const char* loop_event_name(LoopEventKind k) {
  switch (k) {
    case LoopEventKind::kActivated: return "loop parameters active";
    case LoopEventKind::kRejectedParams: return "loop parameters refused";
    case LoopEventKind::kSlip: return "skipped steps (recovered)";
    case LoopEventKind::kEncoderReject: return "implausible encoder sample ignored";
    case LoopEventKind::kEncoderFault: return "encoder fault";
    case LoopEventKind::kFollowingError: return "following error beyond the limit";
    case LoopEventKind::kStopStarted: return "controlled stop started";
    case LoopEventKind::kStopDone: return "controlled stop done (axis at rest)";
    case LoopEventKind::kTargetRejected: return "target knot refused";
  }
  return "unknown loop event";
}

const char* stop_reason_name(StopReason r) {
  switch (r) {
    case StopReason::kNone: return "none";
    case StopReason::kFollowingError: return "following error";
    case StopReason::kEncoderFault: return "encoder fault";
    case StopReason::kTargetHorizon: return "target trajectory ran out while moving";
    case StopReason::kHostSilent: return "host silent (watchdog)";
    case StopReason::kPeer: return "another axis of the MCU stopped";
    case StopReason::kHost: return "host request or bad target stream";
  }
  return "unknown";
}

}  // namespace feedloop::protocol
