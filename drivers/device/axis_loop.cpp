// One axis's device loop: see axis_loop.hpp for the steps of a tick.
#include "drivers/device/axis_loop.hpp"

#include "drivers/device/saturate.hpp"

namespace feedloop::device {

namespace {

// Q16.16 scale: units x (nm per unit x 65536) / 65536 (arithmetic shift: floor).
int64_t q16_mul(int64_t units, uint32_t nm_q16) {
  return mul_saturate_i64(units, static_cast<int64_t>(nm_q16)) >> 16;
}

float absf(float x) { return x < 0.0f ? -x : x; }

int64_t round_to_i64(float x) {
  return round_saturate_i64(x);
}

}  // namespace

void AxisLoop::init(float clock_hz) {
  clock_hz_ = clock_hz;
  inv_hz_ = 1.0f / clock_hz;
  p_ = LoopParams{};
  have_staged_ = false;
  state_ = LoopState::kIdle;
  stop_reason_ = requested_stop_ = StopReason::kNone;
  target_.reset();
  pi_.reset();
  plaus_.reset();
  slip_.reset();
  have_tick_ = false;
  align_pending_ = settle_pending_ = false;
  have_report_origin_ = false;
  have_hold_r_ = false;
  r_nm_ = y_nm_ = hold_r_nm_ = 0;
  e_nm_ = v_ref_nm_s_ = a_ref_nm_s2_ = v_motor_nm_s_ = last_target_slope_nm_s_ = 0.0f;
  last_motor_nm_ = device_steps_ = 0;
  last_step_dir_ = 0;
  step_fraction_ = 0.0f;
  ticks_ = deadline_misses_ = encoder_rejects_ = events_dropped_ = 0;
  max_cost_ = 0;
  ev_head_ = ev_count_ = 0;
}

LoopParamError AxisLoop::stage(const LoopParams& p, int64_t activation_clock) {
  const LoopParamError err = validate_loop_params(p);
  if (err != LoopParamError::kOk) {
    event(LoopEventKind::kRejectedParams, activation_clock, static_cast<int64_t>(err), 0);
    return err;
  }
  staged_ = p;
  staged_clock_ = activation_clock;
  have_staged_ = true;
  return err;
}

bool AxisLoop::push_target(const TargetKnot& k) {
  const bool had = !target_.empty();
  const TargetKnot prev = target_.last();
  if (!target_.push(k)) {
    event(LoopEventKind::kTargetRejected, k.clock, k.pos_nm, target_.free() == 0 ? 0 : 1);
    return false;
  }
  // Nothing was queued ahead of the last tick: r was holding, and this knot starts a motion.
  if (!had || (have_tick_ && prev.clock <= last_tick_clock_)) {
    align_pending_ = true;
    align_clock_ = k.clock;
  }
  last_target_slope_nm_s_ =
      had ? static_cast<float>(k.pos_nm - prev.pos_nm) / static_cast<float>(k.clock - prev.clock) * clock_hz_
          : 0.0f;
  return true;
}

void AxisLoop::request_stop(StopReason why) {
  if (requested_stop_ == StopReason::kNone) requested_stop_ = why;
}

int64_t AxisLoop::next_tick_clock() const {
  int64_t next = kNever;
  if (state_ == LoopState::kRunning || state_ == LoopState::kStopping) next = next_grid_clock_;
  if (have_staged_ && state_ != LoopState::kStopping && staged_clock_ < next) {
    // A staged set applies at the first tick at or after its clock: when running that is a grid
    // tick (next is already the earliest), when idle the activation starts the grid.
    if (state_ != LoopState::kRunning) next = staged_clock_;
  }
  return next;
}

void AxisLoop::event(LoopEventKind k, int64_t clock, int64_t a, int64_t b) {
  if (ev_count_ == kEventCapacity) {
    ++events_dropped_;
    return;
  }
  events_[(ev_head_ + ev_count_) % kEventCapacity] = {k, clock, a, b};
  ++ev_count_;
}

bool AxisLoop::pop_event(LoopEvent& e) {
  if (ev_count_ == 0) return false;
  e = events_[ev_head_];
  ev_head_ = (ev_head_ + 1) % kEventCapacity;
  --ev_count_;
  return true;
}

void AxisLoop::take_report(LoopReport& r) {
  r.clock = last_tick_clock_;
  r.state = state_;
  r.r_nm = r_nm_;
  r.y_nm = y_nm_;
  r.e_nm = e_nm_;
  r.u_nm = pi_.output_nm();
  r.device_steps = device_steps_;
  r.max_tick_cost = max_cost_;
  r.ticks = ticks_;
  r.deadline_misses = deadline_misses_;
  r.encoder_rejects = encoder_rejects_;
  r.slips = slip_.count();
  max_cost_ = 0;
}

void AxisLoop::apply_staged(int64_t clock) {
  const LoopParams p = staged_;
  have_staged_ = false;
  const bool was_running = state_ == LoopState::kRunning;
  if (!p.enabled) {
    // Disabled (the host homes the axis with its own steps, docs/homing.md): the targets queued
    // before are in a frame the homing re-bases, so they are dropped; the next activation starts
    // from an empty queue and holds where the carriage is.
    p_ = p;
    state_ = LoopState::kIdle;
    step_fraction_ = 0.0f;
    target_.reset();
    have_hold_r_ = false;
    last_target_slope_nm_s_ = 0.0f;
    event(LoopEventKind::kActivated, clock, staged_clock_, 0);
    return;
  }
  step_nm_ = static_cast<float>(p.nm_per_step_q16) * (1.0f / 65536.0f);
  count_nm_ = static_cast<float>(p.nm_per_count_q16) * (1.0f / 65536.0f);
  const float per_tick_nm = p.max_correction_rate_nm_s * static_cast<float>(p.period_ticks) * inv_hz_;
  // At most one step per MCU tick of the period (the owner spreads them over it): a valid but
  // huge rate (1e30 nm/s) neither overflows the cast nor asks for billions of steps per tick.
  const int32_t cap = p.period_ticks > static_cast<uint32_t>(INT32_MAX)
                          ? INT32_MAX
                          : static_cast<int32_t>(p.period_ticks);
  max_stop_steps_per_tick_ = cap;
  const float steps = per_tick_nm / step_nm_;
  if (!(steps >= 1.0f))  // NaN too
    max_steps_per_tick_ = 1;
  else if (steps >= static_cast<float>(cap))
    max_steps_per_tick_ = cap;
  else
    max_steps_per_tick_ = static_cast<int32_t>(steps);
  horizon_margin_ticks_ = p.horizon_margin_ticks != 0 ? static_cast<int64_t>(p.horizon_margin_ticks)
                                                      : static_cast<int64_t>(0.02f * clock_hz_);
  plaus_.configure(p.max_speed_nm_s, p.encoder_margin_nm, p.encoder_reject_limit, clock_hz_);
  slip_.configure(p.slip_threshold_nm, p.slip_cycle_nm, p.slip_settle_s);
  if (was_running) {
    pi_.set_gains(p.kp, p.ki_per_s, p.max_correction_nm);  // bumpless
  } else {
    pi_.configure(p.kp, p.ki_per_s, p.max_correction_nm);
    plaus_.reset();
    slip_.reset();
    have_tick_ = false;
    have_hold_r_ = false;
    a_ref_nm_s2_ = 0.0f;
  }
  p_ = p;
  state_ = LoopState::kRunning;
  event(LoopEventKind::kActivated, clock, staged_clock_, 0);
}

int32_t AxisLoop::steps_toward(int64_t want_nm, int64_t have_nm) const {
  const int64_t s = round_to_i64(static_cast<float>(want_nm - have_nm) / step_nm_);
  // Saturated, not wrapped: a wrapped count would step the other way.
  return s > INT32_MAX ? INT32_MAX : s < -INT32_MAX ? -INT32_MAX : static_cast<int32_t>(s);
}

void AxisLoop::begin_stop(StopReason why, int64_t clock, int64_t motor_nm, LoopTickOut& out) {
  stop_reason_ = why;
  state_ = LoopState::kStopping;
  // The speed to brake from: r's slope while r is defined, else the motor's own (filtered); no
  // faster than the axis can move (the encoder plausibility's bound): knots with an absurd slope
  // must not turn the stop into a sprint.
  float v0 = v_ref_nm_s_ != 0.0f ? v_ref_nm_s_ : v_motor_nm_s_;
  if (v0 > p_.max_speed_nm_s) v0 = p_.max_speed_nm_s;
  if (v0 < -p_.max_speed_nm_s) v0 = -p_.max_speed_nm_s;
  ramp_.start(clock, motor_nm, v0, p_.stop_decel_nm_s2, clock_hz_);
  out.flush_host_steps = true;
  event(LoopEventKind::kStopStarted, clock, static_cast<int64_t>(why), saturate_i64(v0));
}

void AxisLoop::stopping_tick(const LoopTickIn& in, int64_t motor_nm, LoopTickOut& out) {
  const int64_t want = ramp_.position_at(next_grid_clock_);
  int32_t n = steps_toward(want, motor_nm);
  if (n > max_stop_steps_per_tick_) n = max_stop_steps_per_tick_;  // one per MCU tick at most
  if (n < -max_stop_steps_per_tick_) n = -max_stop_steps_per_tick_;
  out.extra_steps = n;
  out.over_ticks = next_grid_clock_ - in.clock;
  if (ramp_.done_at(in.clock) && n == 0) {
    state_ = LoopState::kStopped;
    out.stopped = true;
    event(LoopEventKind::kStopDone, in.clock, static_cast<int64_t>(stop_reason_), motor_nm);
  }
}

void AxisLoop::tick(const LoopTickIn& in, LoopTickOut& out) {
  out = LoopTickOut{};
  if (have_staged_ && state_ != LoopState::kStopping && in.clock >= staged_clock_) {
    const bool restart_grid = state_ != LoopState::kRunning;
    apply_staged(in.clock);
    if (restart_grid) {
      have_tick_ = false;
      next_grid_clock_ = in.clock;
    }
  }
  out.step_fraction = step_fraction_;  // held unless step 5 below sets it (0 once disabled)
  if (state_ != LoopState::kRunning && state_ != LoopState::kStopping) return;

  // Time: the tick grid, deadline misses, and the elapsed MCU time since the last tick.
  const int64_t period = p_.period_ticks;
  float dt_s = static_cast<float>(period) * inv_hz_;
  if (have_tick_) {
    if (in.clock - next_grid_clock_ > period / 2) ++deadline_misses_;
    dt_s = static_cast<float>(in.clock - last_tick_clock_) * inv_hz_;
  }
  next_grid_clock_ += period;
  if (next_grid_clock_ <= in.clock) next_grid_clock_ += ((in.clock - next_grid_clock_) / period + 1) * period;
  if (align_pending_) {  // the next tick in (now, now + period], on the motion's first knot's grid
    align_pending_ = false;
    if (align_clock_ > in.clock) {
      next_grid_clock_ = align_clock_ - ((align_clock_ - in.clock - 1) / period) * period;
      report_origin_clock_ = align_clock_;
      have_report_origin_ = true;
      settle_pending_ = true;
      settle_clock_ = align_clock_;
    }
  }
  const bool settle_pi = settle_pending_ && in.clock >= settle_clock_ - period / 2;  // the first knot's tick
  if (settle_pi) settle_pending_ = false;
  const bool first_tick = !have_tick_;
  have_tick_ = true;
  last_tick_clock_ = in.clock;
  ++ticks_;
  device_steps_ = in.device_steps;
  if (p_.report_every_ticks != 0) {
    if (have_report_origin_) {  // on the motion's grid: every motion reports at the same instants of its time
      const int64_t n = (in.clock - report_origin_clock_ + period / 2) / period;  // a late tick keeps its index
      const int64_t every = static_cast<int64_t>(p_.report_every_ticks);
      if (((n % every) + every) % every == 0) out.report_due = true;
    } else if (ticks_ % p_.report_every_ticks == 0) {
      out.report_due = true;
    }
  }

  const int64_t motor_nm = q16_mul(in.motor_steps, p_.nm_per_step_q16);
  if (!first_tick && dt_s > 0.0f) {
    const float v_raw = static_cast<float>(motor_nm - last_motor_nm_) / dt_s;
    const float alpha = dt_s / (dt_s + 0.002f);  // 2 ms filter: the speed a stop brakes from
    v_motor_nm_s_ += alpha * (v_raw - v_motor_nm_s_);
  }
  last_motor_nm_ = motor_nm;

  if (state_ == LoopState::kStopping) {
    stopping_tick(in, motor_nm, out);
    return;
  }

  // 1. Encoder plausibility on timestamps.
  const int64_t y_raw = q16_mul(in.encoder_counts, p_.nm_per_count_q16);
  const EncoderVerdict verdict = plaus_.check(in.clock, y_raw);
  const bool usable = verdict == EncoderVerdict::kGood;
  if (usable) y_nm_ = y_raw;

  // 2. The reference r(t[k]).
  const TargetSample r = target_.at(in.clock, clock_hz_);
  if (r.valid) {
    r_nm_ = r.pos_nm;
  } else {
    if (!have_hold_r_) hold_r_nm_ = y_nm_;  // nothing queued yet: hold where the carriage is
    r_nm_ = hold_r_nm_;
  }
  have_hold_r_ = true;
  hold_r_nm_ = r_nm_;
  const float v_prev = v_ref_nm_s_;
  v_ref_nm_s_ = r.velocity_nm_s;
  if (!first_tick && dt_s > 0.0f) {
    const float a_raw = (v_ref_nm_s_ - v_prev) / dt_s;
    const float alpha = p_.accel_filter_s > 0.0f ? dt_s / (dt_s + p_.accel_filter_s) : 1.0f;
    a_ref_nm_s2_ += alpha * (a_raw - a_ref_nm_s2_);
  }

  // Requested stops and the target horizon (the queue ends while r still moves).
  if (requested_stop_ != StopReason::kNone) {
    const StopReason why = requested_stop_;
    requested_stop_ = StopReason::kNone;
    begin_stop(why, in.clock, motor_nm, out);
    stopping_tick(in, motor_nm, out);
    return;
  }
  if (!target_.empty() && last_target_slope_nm_s_ != 0.0f &&
      target_.horizon_clock() - in.clock < horizon_margin_ticks_) {
    begin_stop(StopReason::kTargetHorizon, in.clock, motor_nm, out);
    stopping_tick(in, motor_nm, out);
    return;
  }

  if (!usable) {
    ++encoder_rejects_;
    const int64_t jump = saturate_i64(plaus_.last_jump_nm());
    const int64_t allowed = saturate_i64(plaus_.last_allowed_nm());
    if (verdict == EncoderVerdict::kFault) {
      event(LoopEventKind::kEncoderFault, in.clock, jump, allowed);
      begin_stop(StopReason::kEncoderFault, in.clock, motor_nm, out);
      stopping_tick(in, motor_nm, out);
      return;
    }
    event(LoopEventKind::kEncoderReject, in.clock, jump, allowed);
    // Hold the correction: no PI update and no slip check on a sample that is not believed.
  } else {
    // 2'. Following error.
    e_nm_ = static_cast<float>(sub_saturate_i64(r_nm_, y_nm_));
    if (absf(e_nm_) > p_.max_following_error_nm) {
      event(LoopEventKind::kFollowingError, in.clock, saturate_i64(e_nm_),
            saturate_i64(p_.max_following_error_nm));
      begin_stop(StopReason::kFollowingError, in.clock, motor_nm, out);
      stopping_tick(in, motor_nm, out);
      return;
    }
    // 3. PI on the elapsed MCU time.
    // With the sub-step trim the motor resolves less than a count, and an integral that keeps
    // summing an error the encoder cannot resolve (r between two counts) dithers the carriage
    // over counts around r: inside one count the integral holds.
    // And the proportional term acts on the error beyond kProportionalBandCounts: a P term on
    // the count-quantised error, delivered below a step by the trim, held the benchy's Y carriage
    // in a 25 Hz limit cycle of +-2.6 counts after a pause's return (its 21 Hz mode stiffened by
    // the friction's presliding; docs/decisions.md); inside the band the integral alone places the
    // carriage, slowly enough not to excite the mode.
    const bool inside_count = p_.sub_step_trim && absf(e_nm_) < count_nm_;
    const float p_band_nm = p_.sub_step_trim ? kProportionalBandCounts * count_nm_ : 0.0f;
    pi_.update(e_nm_, dt_s, !inside_count, p_band_nm);
    if (settle_pi) pi_.set_output(static_cast<float>(in.device_steps) * step_nm_);
    // 4. Skipped steps: motor - carriage against the deflection model, or behind a model inverse
    //    against the lead its steps have over r (the host's steps: all but the loop's own).
    const float deflection =
        p_.deflection_from_host_steps
            ? static_cast<float>(sub_saturate_i64(
                  sub_saturate_i64(motor_nm, q16_mul(in.device_steps, p_.nm_per_step_q16)), r_nm_))
            : p_.deflection_s2 * a_ref_nm_s2_ + p_.deflection_s * v_ref_nm_s_;
    const bool was_pending = slip_.pending();
    const SlipEvent s = slip_.update(static_cast<float>(sub_saturate_i64(motor_nm, y_nm_)),
                                     deflection, dt_s, v_ref_nm_s_);
    if (slip_.pending() && !was_pending) integral_before_slip_nm_ = pi_.integral_nm();
    if (s.happened) {
      // Recovery: make up the lost steps at once (the shift) and drop what the integral gained
      // from the slip's error while it was being confirmed, so the two do not add up.
      pi_.set_integral(integral_before_slip_nm_);
      pi_.shift(s.size_nm);
      event(LoopEventKind::kSlip, in.clock, s.cycles, saturate_i64(s.size_nm));
    }
  }

  // 5. The correction as extra steps over the next period (rate-limited). Rounded, except that a
  // step against the direction of the last one waits until the correction is
  // reversal_hysteresis_steps beyond the rounding threshold (a hysteresis on reversals only: a
  // correction that moves one way is stepped as plain rounding steps it). Plain rounding toggles
  // a step back and forth while the correction hovers at half a step; on a lightly damped
  // carriage that square wave feeds the resonance (the delta's 46-65 Hz electrical mode, |G| up
  // to 48: one toggling 12.5 um step held a 0.6 mm limit cycle with kp 0.01, ki 2;
  // docs/decisions.md).
  const float u_steps = pi_.output_nm() / step_nm_;
  const int64_t u_whole = round_to_i64(u_steps);
  int64_t n = sub_saturate_i64(u_whole, in.device_steps);  // exact in int64
  const float want_f = static_cast<float>(n) + (u_steps - static_cast<float>(u_whole));
  const float back = 0.5f + p_.reversal_hysteresis_steps;
  if ((n > 0 && last_step_dir_ < 0 && want_f < back) || (n < 0 && last_step_dir_ > 0 && want_f > -back)) n = 0;
  if (n != 0) last_step_dir_ = n > 0 ? 1 : -1;
  if (n > max_steps_per_tick_) n = max_steps_per_tick_;
  if (n < -max_steps_per_tick_) n = -max_steps_per_tick_;
  out.extra_steps = static_cast<int32_t>(n);
  out.over_ticks = next_grid_clock_ - in.clock;
  // The rest below one step, as a phase offset of the driver's current (sub_step_trim): with it
  // the motor delivers u itself, not u rounded to steps.
  if (p_.sub_step_trim) {
    float f = u_steps - static_cast<float>(sub_saturate_i64(in.device_steps, -n));
    step_fraction_ = f > 1.0f ? 1.0f : (f < -1.0f ? -1.0f : f);
  } else {
    step_fraction_ = 0.0f;
  }
  out.step_fraction = step_fraction_;
}

}  // namespace feedloop::device
