// The device-side fast loop of one axis (DESIGN.md, "The microcontroller side"; issue 13 item 1),
// on the MCU's clock, at the control rate (period_ticks; 1 kHz default, works at 10 kHz). Each
// tick, with the encoder sampled at the tick's clock t[k]:
//  1. encoder plausibility on timestamps (encoder_plausibility.hpp): an implausible sample is not
//     used; reject_limit in a row trips;
//  2. e = r(t[k]) - y, r from the host's piecewise-linear target queue (target_queue.hpp);
//     |e| > max_following_error trips;
//  3. PI u = K_P e + K_I sum e dt with dt = t[k] - t[k-1] in MCU time (loop_pi.hpp, thesis
//     Sect. 4.6), output clamp, anti-windup;
//  4. skipped steps: motor - y - deflection model - S (slip_detector.hpp); a confirmed slip
//     shifts u by its size (recovery: the motor re-synchronises);
//  5. the correction becomes extra steps: round(u / step) minus the loop's steps already issued,
//     at most max_correction_rate x T per tick, spread by the owner over the next period on top
//     of the host's timed feedforward steps; with sub_step_trim the rest below one step goes out
//     as LoopTickOut::step_fraction (the driver's current phase) and the integral holds while |e|
//     is inside one encoder count;
//  6. watchdog: the target queue about to end while r moves (horizon - t < horizon_margin), the
//     host silent (request_stop from the owner) or a trip start a controlled stop
//     (stop_ramp.hpp): the owner drops the host's queued steps and the loop issues a constant
//     deceleration from r's speed to rest, then reports the axis stopped.
// Parameters (gains, limits, model) are staged with an activation clock and applied at the first
// tick at or after it; the tick grid restarts at the first activation, so a host that states a
// grid clock gets it exactly. A gain change is bumpless (LoopPi::set_gains).
// Counters: ticks, deadline misses (a tick more than half a period late), encoder rejects, slips,
// trips; events go to a fixed ring the owner drains (LOOP_EVENT messages).
// Owner: one thread or interrupt level of the device. Fixed memory, no heap, no locks, no I/O,
// no exceptions, no RTTI (built with -fno-exceptions -fno-rtti, drivers/CMakeLists.txt).
#pragma once

#include <cstdint>

#include "drivers/device/encoder_plausibility.hpp"
#include "drivers/device/loop_params.hpp"
#include "drivers/device/loop_pi.hpp"
#include "drivers/device/slip_detector.hpp"
#include "drivers/device/stop_ramp.hpp"
#include "drivers/device/target_queue.hpp"

namespace feedloop::device {

enum class LoopState : uint8_t { kIdle = 0, kRunning = 1, kStopping = 2, kStopped = 3 };

// Why a controlled stop began (LOOP_EVENT kStopStarted's value a).
enum class StopReason : uint8_t {
  kNone = 0,
  kFollowingError = 1,
  kEncoderFault = 2,
  kTargetHorizon = 3,  // r's queue ends while the axis should still move (host too slow)
  kHostSilent = 4,     // the device's watchdog: no message from the host
  kPeer = 5,           // another axis of the same device stopped
  kHost = 6,           // the host asked (a queue overflow, a bad message...)
};

enum class LoopEventKind : uint8_t {
  kActivated = 1,       // a: requested activation clock, b: LoopParamError (0)
  kRejectedParams = 2,  // a: LoopParamError
  kSlip = 3,            // a: torque-law cycles (x4 = full steps), b: size nm
  kEncoderReject = 4,   // a: distance nm, b: allowed nm
  kEncoderFault = 5,    // a: distance nm, b: allowed nm (trip)
  kFollowingError = 6,  // a: e nm, b: limit nm (trip)
  kStopStarted = 7,     // a: StopReason, b: v0 nm/s
  kStopDone = 8,        // a: StopReason, b: motor position nm
  kTargetRejected = 9,  // a: knot clock, b: 0 = queue full, 1 = clock not increasing
};

struct LoopEvent {
  LoopEventKind kind = LoopEventKind::kActivated;
  int64_t clock = 0;
  int64_t a = 0, b = 0;
};

struct LoopTickIn {
  int64_t clock = 0;           // MCU clock of the encoder sample (the tick's actual time)
  int64_t encoder_counts = 0;
  int64_t motor_steps = 0;     // every executed step: the host's and the loop's
  int64_t device_steps = 0;    // net steps the loop has issued and the owner has executed
};

struct LoopTickOut {
  int32_t extra_steps = 0;        // signed; the owner spreads them over the next period
  int64_t over_ticks = 0;         // that period
  bool flush_host_steps = false;  // a controlled stop began: drop the host's queued steps
  bool stopped = false;           // the controlled stop ended: the axis is at rest
  bool report_due = false;        // a LOOP_REPORT is due (take_report)
  // With sub_step_trim: the correction not delivered in whole steps, in steps (|f| <= 1), for
  // MotorPort::set_step_fraction. 0 without it, and held while the loop stops.
  float step_fraction = 0.0f;
};

// Telemetry of one report window (LOOP_REPORT).
struct LoopReport {
  int64_t clock = 0;
  LoopState state = LoopState::kIdle;
  int64_t r_nm = 0, y_nm = 0;
  float e_nm = 0.0f, u_nm = 0.0f;
  int64_t device_steps = 0;
  uint32_t max_tick_cost = 0;  // owner's unit (ns in the virtual MCU, cycles on a firmware)
  uint64_t ticks = 0, deadline_misses = 0, encoder_rejects = 0, slips = 0;
};

class AxisLoop {
 public:
  static constexpr int kEventCapacity = 32;
  static constexpr int64_t kNever = INT64_MAX;
  // With the sub-step trim: the P term acts on the error beyond this many encoder counts
  // (axis_loop.cpp, step 3).
  static constexpr float kProportionalBandCounts = 3.0f;

  void init(float clock_hz);
  // Stages a parameter set for activation_clock (replacing one not yet applied). Returns the
  // validation result; nothing is staged unless kOk.
  LoopParamError stage(const LoopParams& p, int64_t activation_clock);
  // r(t) knots from the host (QUEUE_TARGET); false when full or not increasing (an event too).
  bool push_target(const TargetKnot& k);  // the first knot of a motion also re-phases the grid
  // Starts a controlled stop at the next tick (host silent, another axis tripped...).
  void request_stop(StopReason why);
  // Clock of the next tick the owner must run (kNever when idle with nothing staged).
  int64_t next_tick_clock() const;
  void tick(const LoopTickIn& in, LoopTickOut& out);
  // The owner's measured cost of the last tick (ns or cycles), kept as the window's maximum.
  void note_tick_cost(uint32_t cost) {
    if (cost > max_cost_) max_cost_ = cost;
  }
  bool pop_event(LoopEvent& e);
  // The report of the window since the last call (resets the window's maximum cost).
  void take_report(LoopReport& r);

  LoopState state() const { return state_; }
  bool active() const { return state_ == LoopState::kRunning || state_ == LoopState::kStopping; }
  StopReason stop_reason() const { return stop_reason_; }
  const LoopParams& params() const { return p_; }
  const LoopPi& pi() const { return pi_; }
  const SlipDetector& slip() const { return slip_; }
  const TargetQueue& target() const { return target_; }
  float last_error_nm() const { return e_nm_; }
  int64_t last_y_nm() const { return y_nm_; }
  int64_t last_r_nm() const { return r_nm_; }
  uint64_t ticks() const { return ticks_; }
  uint64_t deadline_misses() const { return deadline_misses_; }
  uint64_t encoder_rejects() const { return encoder_rejects_; }
  uint64_t events_dropped() const { return events_dropped_; }

 private:
  void apply_staged(int64_t clock);
  void begin_stop(StopReason why, int64_t clock, int64_t motor_nm, LoopTickOut& out);
  void stopping_tick(const LoopTickIn& in, int64_t motor_nm, LoopTickOut& out);
  void event(LoopEventKind k, int64_t clock, int64_t a, int64_t b);
  int32_t steps_toward(int64_t want_nm, int64_t have_nm) const;

  float clock_hz_ = 1.0f, inv_hz_ = 1.0f;
  LoopParams p_{};
  LoopParams staged_{};
  bool have_staged_ = false;
  int64_t staged_clock_ = 0;

  LoopState state_ = LoopState::kIdle;
  StopReason stop_reason_ = StopReason::kNone;
  StopReason requested_stop_ = StopReason::kNone;
  TargetQueue target_;
  LoopPi pi_;
  EncoderPlausibility plaus_;
  SlipDetector slip_;
  StopRamp ramp_;

  // Tick grid.
  bool have_tick_ = false;
  int64_t last_tick_clock_ = 0;   // actual clock of the last tick
  int64_t next_grid_clock_ = 0;   // scheduled clock of the next tick
  // A motion's first knot, pushed while r was holding (nothing queued ahead): the grid is moved
  // so that a tick falls on it. Every motion is then sampled at the same instants of its own
  // time, wherever the host's clock frame put its start (docs/decisions.md, "One motion, one
  // clock frame").
  bool align_pending_ = false;
  int64_t align_clock_ = 0;
  // The tick on a motion's first knot sets the PI's output to the correction already stepped
  // (device_steps): what the integral gathered at rest below one step, over however long the
  // carriage waited (and the knot arrived ahead), does not carry into the motion, so a motion
  // starts from the same loop state whenever it starts (issue 13's wall-clock comparison;
  // docs/decisions.md, "One motion, one clock frame").
  bool settle_pending_ = false;
  int64_t settle_clock_ = 0;
  bool have_report_origin_ = false;  // LOOP_REPORTs every report_every_ticks of that grid
  int64_t report_origin_clock_ = 0;
  // Derived from p_.
  int32_t max_steps_per_tick_ = 1;       // correction steps per tick (the rate limit)
  int32_t max_stop_steps_per_tick_ = 1;  // steps per tick of a controlled stop: one per MCU tick
  float step_nm_ = 1.0f;
  float count_nm_ = 1.0f;  // one encoder count
  int64_t horizon_margin_ticks_ = 0;
  // Last tick's values.
  int64_t r_nm_ = 0, y_nm_ = 0, hold_r_nm_ = 0;
  bool have_hold_r_ = false;
  float e_nm_ = 0.0f, v_ref_nm_s_ = 0.0f, a_ref_nm_s2_ = 0.0f;
  float v_motor_nm_s_ = 0.0f;
  int64_t last_motor_nm_ = 0;
  float last_target_slope_nm_s_ = 0.0f;  // slope of the queue's last piece
  int64_t device_steps_ = 0;
  int last_step_dir_ = 0;  // direction of the last correction step (the reversal hysteresis)
  float integral_before_slip_nm_ = 0.0f;
  float step_fraction_ = 0.0f;  // the last tick's LoopTickOut::step_fraction

  // Counters.
  uint64_t ticks_ = 0, deadline_misses_ = 0, encoder_rejects_ = 0, events_dropped_ = 0;
  uint32_t max_cost_ = 0;

  LoopEvent events_[kEventCapacity];
  int ev_head_ = 0, ev_count_ = 0;
};

}  // namespace feedloop::device
