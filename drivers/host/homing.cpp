// Homing sequence: see homing.hpp.
#include "drivers/host/homing.hpp"

#include <algorithm>  // max
#include <cmath>   // sqrt, isfinite, llround
#include <cstdio>  // snprintf

#include "drivers/protocol/endstop_messages.hpp"
#include "drivers/stepgen/run_codec.hpp"

namespace feedloop::drivers {

namespace {
bool positive(double v) {
  return std::isfinite(v) && v > 0.0;
}
}  // namespace

Status check_homing_params(const HomingParams& p) {
  // The message is built only when a check fails: a valid set allocates nothing (the servo thread
  // starts a homing with it, engine/mcu_bridge.cpp).
  auto bad = [&](const char* what) { return Error{"homing of " + p.axis_name + ": " + what, {}}; };
  if (!positive(p.mm_per_step)) return bad("mm_per_step must be > 0");
  if (!std::isfinite(p.position_endstop_mm)) return bad("position_endstop must be finite");
  if (p.direction != 1 && p.direction != -1) return bad("direction must be -1 (min) or +1 (max)");
  if (!positive(p.max_travel_mm)) return bad("max travel must be > 0");
  if (!positive(p.homing_speed_mm_s)) return bad("homing_speed must be > 0");
  if (!positive(p.second_homing_speed_mm_s)) return bad("second_homing_speed must be > 0");
  if (!positive(p.accel_mm_s2)) return bad("acceleration must be > 0");
  if (p.second_touch && !positive(p.retract_dist_mm))
    return bad("retract_dist must be > 0 for a second touch");
  if (!positive(p.sample_period_s) || p.sample_period_s > 0.01)
    return bad("endstop sample period must be in (0, 10 ms]");
  if (p.sample_count < 1 || p.sample_count > 255)
    return bad("endstop sample_count must be in 1..255");
  // The MCU needs the sample_count samples to confirm: the carriage overshoots the trigger by
  // speed * count * period before the steps stop; more than the retract would be a crash.
  const double overshoot_mm = p.homing_speed_mm_s * p.sample_period_s * p.sample_count;
  if (p.second_touch && overshoot_mm >= p.retract_dist_mm)
    return bad("homing_speed * sample time overshoots the retract distance");
  if (!positive(p.queue_ahead_s)) return bad("queue_ahead must be > 0");
  if (p.motor_sign != 1 && p.motor_sign != -1) return bad("motor_sign must be -1 or +1");
  if (p.has_follower && p.follower_sign != 1 && p.follower_sign != -1)
    return bad("follower_sign must be -1 or +1");
  if (p.stall && (!p.report_encoder || p.second_touch || !positive(p.encoder_mm_per_count) ||
                  !positive(p.stall_threshold_mm) || p.stall_backoff_mm < 0.0 ||
                  p.mm_per_step / p.encoder_mm_per_count > 60000.0))
    return bad("stall homing needs the encoder's count, no second touch and a threshold > 0");
  if (p.index_search && (!positive(p.index_search_mm) || !p.report_encoder))
    return bad("encoder-index homing needs the encoder's count and a search distance > 0");
  return {};
}

double HomingSequence::Move::duration() const {
  double ta = v / a, da = 0.5 * a * ta * ta, vp = v;
  if (2.0 * da > d_mm) {
    vp = std::sqrt(a * d_mm);
    ta = vp / a;
    da = 0.5 * d_mm;
  }
  return 2.0 * ta + (d_mm - 2.0 * da) / vp;
}

double HomingSequence::Move::time_at(double x) const {
  double ta = v / a, da = 0.5 * a * ta * ta, vp = v;
  if (2.0 * da > d_mm) {
    vp = std::sqrt(a * d_mm);
    ta = vp / a;
    da = 0.5 * d_mm;
  }
  if (x <= da) return std::sqrt(2.0 * x / a);
  if (x <= d_mm - da) return ta + (x - da) / vp;
  const double rest = x < d_mm ? d_mm - x : 0.0;
  return duration() - std::sqrt(2.0 * rest / a);
}

HomingSequence::HomingSequence(const HomingParams& params, McuSession& session,
                               McuSession* follower_session)
    : p_(params), session_(session), fsession_(follower_session ? *follower_session : session) {}

double HomingSequence::mcu_s(double host_s) const {
  return session_.tick_map().ticks(host_s);
}

void HomingSequence::abort(const char* why) {
  if (phase_ == HomingPhase::kDone || phase_ == HomingPhase::kFailed ||
      phase_ == HomingPhase::kIdle)
    return;
  fail(std::string("homing of ") + p_.axis_name + " aborted: " + why);
}

void HomingSequence::fail(std::string message) {
  error_ = Error{std::move(message), {}};
  phase_ = HomingPhase::kFailed;
  streaming_ = false;
  arm(false);
  if (p_.has_follower) arm_motor(fsession_, p_.follower_motor, false, protocol::EndstopSource::kPin);
}

void HomingSequence::arm(bool on) {
  arm_motor(session_, p_.motor, on,
            p_.stall ? protocol::EndstopSource::kStall : protocol::EndstopSource::kPin,
            p_.report_encoder && session_.negotiated_version() >= 4
                ? protocol::kEndstopReportEncoder
                : 0);
}

void HomingSequence::arm_motor(McuSession& s, uint8_t motor, bool on,
                               protocol::EndstopSource source, uint8_t flags) {
  protocol::EndstopHomeMsg m;
  m.axis = motor;
  m.trigger_level = 1;
  m.sample_ticks =
      on ? static_cast<uint32_t>(std::llround(p_.sample_period_s * s.mcu_clock_hz())) : 0;
  if (on && m.sample_ticks == 0) m.sample_ticks = 1;
  // An index line is a clean digital signal one count wide: the first sample on it is the mark.
  m.sample_count =
      static_cast<uint8_t>(source == protocol::EndstopSource::kEncoderIndex ? 1 : p_.sample_count);
  m.source = on ? source : protocol::EndstopSource::kPin;
  m.flags = on ? flags : 0;
  if (m.source == protocol::EndstopSource::kStall) {
    m.stall_counts_per_step_q16 =
        static_cast<uint32_t>(std::llround(p_.mm_per_step / p_.encoder_mm_per_count * 65536.0));
    m.stall_threshold_counts = static_cast<uint32_t>(
        std::max(1.0, std::round(p_.stall_threshold_mm / p_.encoder_mm_per_count)));
  }
  uint8_t buf[32];
  const size_t n = protocol::encode_endstop_home(m, buf, sizeof buf);
  if (n > 0) s.queue_message(buf, n);
}

Status HomingSequence::start(int64_t position_steps, double now_s) {
  if (Status s = check_homing_params(p_); !s) return s;
  if (!session_.ready()) return Error{"homing of " + p_.axis_name + ": the MCU is not ready", {}};
  if (session_.negotiated_version() < 3)
    return Error{"homing of " + p_.axis_name + ": the MCU speaks protocol " +
                     std::to_string(session_.negotiated_version()) + ", endstops need 3",
                 {}};
  // Stale triggers and states of an earlier sequence are not this one's.
  if (p_.has_follower) {
    if (!fsession_.ready())
      return Error{"homing of " + p_.axis_name + ": the second motor's MCU is not ready", {}};
    if (fsession_.negotiated_version() < 3)
      return Error{"homing of " + p_.axis_name + ": the second motor's MCU speaks protocol " +
                       std::to_string(fsession_.negotiated_version()) + ", endstops need 3",
                   {}};
    if (&fsession_ == &session_ && p_.follower_motor == p_.motor)
      return Error{"homing of " + p_.axis_name + ": the second motor is the first", {}};
  }
  protocol::EndstopTriggerMsg t[16];
  while (session_.take_endstop_triggers(t, 16) > 0) {
  }
  while (fsession_.take_endstop_triggers(t, 16) > 0) {
  }
  protocol::EndstopStateMsg st[16];
  while (session_.take_endstop_states(st, 16) > 0) {
  }
  pos_steps_ = position_steps;
  error_.reset();
  result_ = {};
  queued_any_ = f_queued_any_ = false;
  if (p_.has_follower) {
    // Where both motors are, in their MCUs' frames (the lockstep needs both): a kNow trigger at
    // rest stops nothing and reports the position.
    located_p_ = located_f_ = false;
    f_pos_steps_ = 0;
    phase_ = HomingPhase::kLocate;
    wait_since_s_ = now_s;
    arm_motor(session_, p_.motor, true, protocol::EndstopSource::kNow);
    arm_motor(fsession_, p_.follower_motor, true, protocol::EndstopSource::kNow);
    return {};
  }
  phase_ = HomingPhase::kApproach;
  arm(true);
  begin_move(p_.direction * p_.max_travel_mm, p_.homing_speed_mm_s, now_s);
  return {};
}

void HomingSequence::begin_move(double distance_mm, double speed_mm_s, double now_s) {
  move_.dir = distance_mm >= 0.0 ? 1 : -1;
  move_.d_mm = std::abs(distance_mm);
  move_.v = speed_mm_s;
  move_.a = p_.accel_mm_s2;
  // Each phase starts at most kHomingStartLead_s ahead (three phases of a G28 would wait the whole
  // lead each); its steps are then streamed up to the full lead ahead.
  move_.t0 = now_s + std::min(p_.queue_ahead_s, kHomingStartLead_s);
  move_start_steps_ = pos_steps_;
  f_move_start_steps_ = f_pos_steps_;
  move_steps_total_ = static_cast<int64_t>(std::floor(move_.d_mm / p_.mm_per_step));
  move_steps_sent_ = 0;
  have_last_clock_ = false;
  f_have_last_clock_ = false;
  streaming_ = true;
  stream(now_s);
}

void HomingSequence::stream(double now_s) {
  if (!streaming_) return;
  // Single-step runs: a long queue_ahead at homing speed would be more runs than the MCU holds
  // (4716 steps/s at 50 mm/s x 94.3 steps/mm, 4096 runs per motor: a 1 s lead overflowed it).
  // The homing lead is at most kHomingRunBudget steps of the fast approach.
  const double step_rate_hz = std::max(move_.v, p_.homing_speed_mm_s) / p_.mm_per_step;
  const double horizon_s = now_s + std::min(p_.queue_ahead_s, kHomingRunBudget / step_rate_hz);
  const int dir = move_.dir * p_.motor_sign;
  const int fdir = move_.dir * p_.follower_sign;
  // A run takes at most this many bytes (RunEncoder::append's scratch): a batch stops before
  // either message could refuse one, so both motors always get the same steps.
  constexpr size_t kRunMax = 32;
  while (move_steps_sent_ < move_steps_total_) {
    uint8_t msg[protocol::kMaxPayload], fmsg[protocol::kMaxPayload];
    msg[0] = fmsg[0] = static_cast<uint8_t>(protocol::MsgType::kQueueSteps);
    msg[1] = p_.motor;
    fmsg[1] = p_.follower_motor;
    const int64_t first = have_last_clock_ ? last_step_clock_ : std::llround(mcu_s(move_.t0));
    const int64_t ffirst = f_have_last_clock_
                               ? f_last_step_clock_
                               : std::llround(fsession_.tick_map().ticks(move_.t0));
    stepgen::RunEncoder enc, fenc;
    enc.begin(msg + 2, protocol::kMaxPayload - 2, static_cast<uint64_t>(first));
    if (p_.has_follower) fenc.begin(fmsg + 2, protocol::kMaxPayload - 2, static_cast<uint64_t>(ffirst));
    int64_t prev = first, fprev = ffirst;
    int count = 0;
    while (move_steps_sent_ < move_steps_total_ && count < 64) {
      if (p_.has_follower && (enc.size() + kRunMax > protocol::kMaxPayload - 2 ||
                              fenc.size() + kRunMax > protocol::kMaxPayload - 2))
        break;
      // Step k is taken when the ideal position passes (k - 1/2) steps (round to nearest).
      const double x_mm = (static_cast<double>(move_steps_sent_) + 0.5) * p_.mm_per_step;
      const double ts = move_.t0 + move_.time_at(x_mm);
      if (ts > horizon_s) break;
      int64_t c = std::llround(mcu_s(ts));
      if (c <= prev) c = prev + 1;
      stepgen::StepRun run;
      run.interval_ticks = c - prev;
      run.count = 1;
      run.direction = static_cast<int8_t>(dir);
      if (!enc.append(run)) break;
      if (p_.has_follower) {
        // The same host time on the follower's clock: the two motors step in lockstep.
        int64_t fc = std::llround(fsession_.tick_map().ticks(ts));
        if (fc <= fprev) fc = fprev + 1;
        stepgen::StepRun frun;
        frun.interval_ticks = fc - fprev;
        frun.count = 1;
        frun.direction = static_cast<int8_t>(fdir);
        fenc.append(frun);  // fits: checked above
        fprev = fc;
      }
      prev = c;
      ++move_steps_sent_;
      ++count;
    }
    if (count == 0) break;
    session_.queue_message(msg, 2 + enc.size());
    last_step_clock_ = prev;
    have_last_clock_ = true;
    queued_any_ = true;
    pos_steps_ += static_cast<int64_t>(count) * dir;
    if (p_.has_follower) {
      fsession_.queue_message(fmsg, 2 + fenc.size());
      f_last_step_clock_ = fprev;
      f_have_last_clock_ = true;
      f_queued_any_ = true;
      f_pos_steps_ += static_cast<int64_t>(count) * fdir;
    }
  }
}

bool HomingSequence::move_done(double now_s, double margin_s) const {
  // Every step sent and the last one executed, with a margin for the link's latency.
  return move_steps_sent_ >= move_steps_total_ && now_s > move_.t0 + move_.duration() + margin_s;
}

void HomingSequence::take_triggers(double now_s) {
  protocol::EndstopTriggerMsg trig[4];
  const bool shared = &fsession_ == &session_;
  for (size_t nt = 4; nt == 4;) {
    nt = session_.take_endstop_triggers(trig, 4);
    for (size_t i = 0; i < nt; ++i) {
      if (phase_ == HomingPhase::kFailed || phase_ == HomingPhase::kDone) return;
      if (trig[i].axis == p_.motor)
        on_primary_trigger(trig[i], now_s);
      else if (p_.has_follower && shared && trig[i].axis == p_.follower_motor)
        on_follower_trigger(trig[i], now_s);
    }
  }
  if (!p_.has_follower || shared) return;
  for (size_t nt = 4; nt == 4;) {
    nt = fsession_.take_endstop_triggers(trig, 4);
    for (size_t i = 0; i < nt; ++i) {
      if (phase_ == HomingPhase::kFailed || phase_ == HomingPhase::kDone) return;
      if (trig[i].axis == p_.follower_motor) on_follower_trigger(trig[i], now_s);
    }
  }
}

void HomingSequence::on_primary_trigger(const protocol::EndstopTriggerMsg& t, double now_s) {
  if (phase_ == HomingPhase::kLocate) {
    if (!located_p_) pos_steps_ = result_.start_steps = t.stop_steps;
    located_p_ = true;
    return;
  }
  if (phase_ == HomingPhase::kIndexSearch) {
    streaming_ = false;
    pos_steps_ = t.stop_steps;
    arm_motor(session_, p_.motor, false, protocol::EndstopSource::kPin);
    if (!t.has_encoder) {
      fail("homing of " + p_.axis_name + ": the MCU did not report the encoder count at the index");
      return;
    }
    result_.has_index = true;
    result_.index_encoder_counts = t.trigger_encoder_counts;
    if (p_.has_follower) {  // the follower stops on the relay too, then the result
      primary_trigger_ = t;
      stopped_in_ = HomingPhase::kIndexSearch;
      phase_ = HomingPhase::kFollowerStop;
      wait_since_s_ = now_s;
      arm_motor(fsession_, p_.follower_motor, true, protocol::EndstopSource::kNow);
      return;
    }
    finish_at(t.stop_steps);
    return;
  }
  if (phase_ != HomingPhase::kApproach && phase_ != HomingPhase::kSecondTouch) return;  // stale
  streaming_ = false;
  pos_steps_ = t.stop_steps;  // the MCU's word: what it executed before it stopped
  arm(false);
  stopped_in_ = phase_;
  if (p_.has_follower) {
    // Relay the stop to the follower at once; it goes on until the message arrives.
    // With the encoders' counts, the follower's at its stop too (CoreXY stall homing: both belts
    // are held by the hard stop until the back-off).
    primary_trigger_ = t;
    phase_ = HomingPhase::kFollowerStop;
    wait_since_s_ = now_s;
    arm_motor(fsession_, p_.follower_motor, true, protocol::EndstopSource::kNow,
              p_.report_encoder && fsession_.negotiated_version() >= 4
                  ? protocol::kEndstopReportEncoder
                  : 0);
    return;
  }
  after_stop(t, now_s);
}

// Where the motors stopped (the primary at primary_stop_steps, the follower where the host has it)
// and the axis's position there: the trigger's plus the travel since, with a follower the mean of
// both motors' (CoreXY: x = (A + B) / 2, y = (A - B) / 2).
void HomingSequence::set_result_at(int64_t primary_stop_steps) {
  result_.stop_steps = primary_stop_steps;
  double moved_steps =
      static_cast<double>(p_.motor_sign * (primary_stop_steps - result_.trigger_steps));
  if (p_.has_follower) {
    result_.follower_stop_steps = f_pos_steps_;
    moved_steps = 0.5 * (moved_steps +
                         static_cast<double>(p_.follower_sign * (result_.follower_stop_steps -
                                                                 result_.follower_trigger_steps)));
  }
  result_.position_mm = p_.position_endstop_mm + moved_steps * p_.mm_per_step;
}

void HomingSequence::finish_at(int64_t primary_stop_steps) {
  set_result_at(primary_stop_steps);
  phase_ = HomingPhase::kDone;
}

void HomingSequence::on_follower_trigger(const protocol::EndstopTriggerMsg& t, double now_s) {
  if (phase_ == HomingPhase::kLocate) {
    if (!located_f_) f_pos_steps_ = result_.follower_start_steps = t.stop_steps;
    located_f_ = true;
    return;
  }
  if (phase_ != HomingPhase::kFollowerStop) return;  // stale
  f_pos_steps_ = t.stop_steps;
  arm_motor(fsession_, p_.follower_motor, false, protocol::EndstopSource::kPin);
  // Lockstep: the follower took follower_sign * motor_sign steps for each of the primary's.
  const int64_t f_at_primary_stop =
      f_move_start_steps_ + p_.follower_sign * p_.motor_sign *
                                (primary_trigger_.stop_steps - move_start_steps_);
  const int64_t lag = f_pos_steps_ - f_at_primary_stop;
  result_.relay_lag_steps = std::max(result_.relay_lag_steps, lag < 0 ? -lag : lag);
  if (stopped_in_ == HomingPhase::kIndexSearch) {
    finish_at(primary_trigger_.stop_steps);
    return;
  }
  result_.has_follower_encoder = t.has_encoder;
  result_.follower_stop_encoder_counts = t.trigger_encoder_counts;
  after_stop(primary_trigger_, now_s);
}

// Every motor of the touch stopped (the primary at its trigger t): retract for the second touch,
// or the result.
void HomingSequence::after_stop(const protocol::EndstopTriggerMsg& t, double now_s) {
  if (stopped_in_ == HomingPhase::kApproach) {
    first_trigger_steps_ = t.trigger_steps;
    if (p_.second_touch) {
      phase_ = HomingPhase::kRetract;
      begin_move(-p_.direction * p_.retract_dist_mm, p_.homing_speed_mm_s, now_s);
      return;
    }
  }
  result_.trigger_steps = t.trigger_steps;
  result_.has_trigger_encoder = p_.report_encoder && t.has_encoder;  // only when asked for
  result_.trigger_encoder_counts = t.trigger_encoder_counts;
  if (p_.has_follower)  // where the follower was when the primary's switch tripped (the lockstep)
    result_.follower_trigger_steps =
        f_move_start_steps_ +
        p_.follower_sign * p_.motor_sign * (t.trigger_steps - move_start_steps_);
  set_result_at(t.stop_steps);
  result_.first_trigger_mm =
      p_.position_endstop_mm +
      static_cast<double>(p_.motor_sign * (first_trigger_steps_ - result_.trigger_steps)) *
          p_.mm_per_step;
  if (p_.stall && p_.stall_backoff_mm > 0.0) {
    // Off the hard stop, so that the steps and the carriage agree again at rest.
    phase_ = HomingPhase::kBackoff;
    begin_move(-p_.direction * p_.stall_backoff_mm, p_.second_homing_speed_mm_s, now_s);
    return;
  }
  if (p_.index_search) {
    // Away from the switch to the encoder's next index mark (its count is the reference).
    phase_ = HomingPhase::kIndexSearch;
    arm_motor(session_, p_.motor, true, protocol::EndstopSource::kEncoderIndex,
              protocol::kEndstopReportEncoder);
    // Slow enough that the one-count-wide line spans 4 of the MCU's samples (a sampled line, not a
    // latched edge): 0.49 um / 200 us = 2.45 mm/s on the thesis encoder.
    double v = p_.second_homing_speed_mm_s;
    if (p_.encoder_mm_per_count > 0.0)
      v = std::min(v, p_.encoder_mm_per_count / (4.0 * p_.sample_period_s));
    begin_move(-p_.direction * p_.index_search_mm, v, now_s);
    return;
  }
  phase_ = HomingPhase::kDone;
}

HomingPhase HomingSequence::poll(double now_s) {
  if (phase_ == HomingPhase::kIdle || phase_ == HomingPhase::kDone ||
      phase_ == HomingPhase::kFailed)
    return phase_;
  if (session_.state() == McuState::kFailed) {
    fail("homing of " + p_.axis_name +
         " stopped: " + (session_.error() ? session_.error()->message : "MCU failed"));
    return phase_;
  }
  if (p_.has_follower && fsession_.state() == McuState::kFailed) {
    fail("homing of " + p_.axis_name +
         " stopped: " + (fsession_.error() ? fsession_.error()->message : "MCU failed"));
    return phase_;
  }
  take_triggers(now_s);
  if (phase_ == HomingPhase::kFailed || phase_ == HomingPhase::kDone) return phase_;
  if (phase_ == HomingPhase::kLocate) {
    if (located_p_ && located_f_) {
      arm_motor(fsession_, p_.follower_motor, false, protocol::EndstopSource::kPin);
      phase_ = HomingPhase::kApproach;
      arm(true);  // disarms the kNow trigger and arms the switch
      begin_move(p_.direction * p_.max_travel_mm, p_.homing_speed_mm_s, now_s);
    } else if (now_s - wait_since_s_ > 1.0) {
      fail("homing of " + p_.axis_name + ": the MCUs did not report the motors' positions");
    }
    return phase_;
  }
  if (phase_ == HomingPhase::kFollowerStop) {
    if (now_s - wait_since_s_ > 1.0)
      fail("homing of " + p_.axis_name + ": the second motor did not report its stop");
    return phase_;
  }
  stream(now_s);
  switch (phase_) {
    case HomingPhase::kApproach:
    case HomingPhase::kSecondTouch:
      if (move_done(now_s, 0.1)) {  // 0.1 s for a trigger report to arrive
        char buf[96];
        std::snprintf(buf, sizeof buf, " after full movement (%.3f mm)", move_.d_mm);
        fail("No trigger on " + p_.axis_name + buf);  // Klipper's wording (homing.py)
      }
      break;
    case HomingPhase::kBackoff:
      // The belt rings out before the result (and before a next sequence arms on these motors).
      if (move_done(now_s, 0.15)) finish_at(pos_steps_);
      break;
    case HomingPhase::kIndexSearch:
      if (move_done(now_s, 0.1)) {
        char buf[96];
        std::snprintf(buf, sizeof buf, " within %.3f mm of the switch", move_.d_mm);
        fail("No encoder index on " + p_.axis_name + buf);
      }
      break;
    case HomingPhase::kRetract:
      if (move_done(now_s, 0.02)) {
        // Answers to earlier queries (the owner's M119 polling) are not this one's.
        protocol::EndstopStateMsg stale[8];
        while (session_.take_endstop_states(stale, 8) > 0) {
        }
        protocol::EndstopQueryMsg q;
        q.axis = p_.motor;
        uint8_t buf[8];
        const size_t n = protocol::encode_endstop_query(q, buf, sizeof buf);
        if (n > 0) session_.queue_message(buf, n);
        query_sent_s_ = now_s;
        phase_ = HomingPhase::kCheckRelease;
      }
      break;
    case HomingPhase::kCheckRelease: {
      protocol::EndstopStateMsg st[4];
      const size_t ns = session_.take_endstop_states(st, 4);
      for (size_t i = 0; i < ns; ++i) {
        if (st[i].axis != p_.motor) continue;
        if (st[i].pin != 0) {
          fail("Endstop " + p_.axis_name + " still triggered after retract");  // Klipper's wording
          return phase_;
        }
        phase_ = HomingPhase::kSecondTouch;
        arm(true);
        begin_move(p_.direction * 2.0 * p_.retract_dist_mm, p_.second_homing_speed_mm_s, now_s);
        return phase_;
      }
      if (now_s - query_sent_s_ > 1.0)
        fail("homing of " + p_.axis_name + ": the MCU did not answer the endstop query");
      break;
    }
    default:
      break;
  }
  return phase_;
}

}  // namespace feedloop::drivers
