// Homing of one motor against its endstop through an McuSession (protocol v3,
// endstop_messages.hpp), the sequence Klipper's homing.py runs: a fast approach at homing_speed
// until the switch triggers, a retract of homing_retract_dist, a check that the switch released
// ("Endstop x still triggered after retract"), and a slow second touch at second_homing_speed. The
// MCU stops the steps at the trigger and reports the step position of the first triggered sample;
// the host derives the motor's position from it: at that step position the carriage was at
// position_endstop_mm (Klipper: the trigger time's step position, stepper.get_past_mcu_position).
//
// The sequencer streams its own steps (single-step runs, queue_ahead_s ahead of the MCU clock),
// from rest, trapezoidal (accel_mm_s2). Driven by poll(now_s) after session.poll(now_s).
// A second motor can move with the first (a CoreXY carriage: X = (A + B) / 2 moves A and B
// together, Klipper's corexy.py): the sequence streams it the same step times, and when the
// primary motor's switch trips, the host relays the stop to it at once (ENDSTOP_HOME with source
// kNow, on its own MCU or the same one: Klipper's trsync relayed by the host) and takes the step
// position it stopped at. Where the follower was at the trigger follows from the lockstep of the
// two streams; the homed position is the endstop plus the mean of both motors' steps after the
// trigger (docs/decisions.md "CoreXY homing").
// Owner: the thread that owns the session. Not real-time (it allocates nothing per step, but builds
// error strings).
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "core/result.hpp"
#include "drivers/host/mcu_session.hpp"
#include "drivers/protocol/endstop_messages.hpp"

namespace feedloop::drivers {

// At most this many of a homing's single-step runs are queued on the MCU ahead of its clock: half
// the run queue of a motor (docs/protocol.md: 4096), whatever stepgen.queue_ahead_ms is.
inline constexpr double kHomingRunBudget = 2048.0;
// A homing phase's first step is due at most this long after it is started.
inline constexpr double kHomingStartLead_s = 0.1;

struct HomingParams {
  std::string axis_name = "x";       // in messages
  uint8_t motor = 0;                 // motor index on the MCU
  double mm_per_step = 0.005;        // (the joint's) mm per step
  double position_endstop_mm = 0.0;  // where the switch triggers
  int direction = -1;                // -1: the switch is at the low end (a min endstop), +1: max
  double max_travel_mm =
      300.0;  // the fast approach's longest move ("No trigger ... after full movement")
  double homing_speed_mm_s = 50.0;  // Klipper's homing_speed default: 5 mm/s; printers use 20-50
  double second_homing_speed_mm_s = 5.0;
  double retract_dist_mm = 5.0;  // Klipper's homing_retract_dist default
  double accel_mm_s2 = 1000.0;
  double sample_period_s = 50e-6;  // endstop sampling on the MCU
  int sample_count = 4;  // consecutive samples to confirm (Klipper: ENDSTOP_SAMPLE_COUNT 4)
  double queue_ahead_s = 0.1;  // bounded by kHomingRunBudget single-step runs in flight
  bool second_touch = true;  // false: only the fast approach (Klipper: retract_dist 0)
  // The motor's steps per step of the homed axis: +1, or -1 when the motor turns the other way
  // (CoreXY Y through motor B: B = x - y).
  int motor_sign = 1;
  // A second motor that moves with the first (see above): follower_sign steps per axis step, on
  // the MCU of the follower session given to the constructor (the same session: another motor).
  bool has_follower = false;
  uint8_t follower_motor = 0;
  int follower_sign = 1;
  // Ask the MCU for the motor's encoder count at the trigger (protocol v4; the owner sets it for
  // a joint with a linear encoder): the owner then refers the homed position to the carriage, not
  // to the steps (docs/homing.md "Carriage-referenced homing"). An older MCU: the steps only.
  bool report_encoder = false;
  // Encoder-index homing (docs/homing.md "Encoder-index homing"; needs report_encoder and an MCU
  // with protocol v4; with a follower, it moves too and stops on the relay): after the last
  // touch the motor moves away from the switch at
  // second_homing_speed until the encoder's index line triggers (ENDSTOP_HOME source
  // kEncoderIndex), at most index_search_mm. The switch picks the mark; the mark is the reference.
  bool index_search = false;
  double index_search_mm = 0.0;
  // Stall (sensorless) homing against a hard stop at position_endstop (docs/homing.md "Stall
  // homing"; needs report_encoder): the approach is armed with ENDSTOP_HOME source kStall: the MCU
  // trips when the encoder falls stall_threshold_mm behind the steps. No second touch; then the
  // motor backs off stall_backoff_mm at second_homing_speed (off the stop, the belt relaxed).
  // With a follower (CoreXY): the primary's encoder trips, the follower stops on the relay.
  bool stall = false;
  double stall_threshold_mm = 0.5;
  double stall_backoff_mm = 1.0;
  double encoder_mm_per_count = 0.0;  // the stall's comparison; the index search's speed limit
};

Status check_homing_params(const HomingParams& p);

// kLocate: a sequence with a follower first asks both motors where they are (kNow triggers at
// rest); kFollowerStop: the primary triggered, the follower's relayed stop is awaited.
enum class HomingPhase {
  kIdle,
  kLocate,
  kApproach,
  kRetract,
  kCheckRelease,
  kSecondTouch,
  kIndexSearch,
  kBackoff,
  kFollowerStop,
  kDone,
  kFailed
};

struct HomingResult {
  int64_t trigger_steps = 0;  // the step position at the (final) trigger
  int64_t stop_steps = 0;     // where the motor stopped
  // The motor's position at stop_steps: position_endstop + (stop - trigger) * mm_per_step.
  double position_mm = 0.0;
  double first_trigger_mm = 0.0;  // the fast approach's trigger, in the final frame (diagnostics)
  // With a follower (each motor's step counts in its MCU's frame): where both started, where the
  // follower was at the final trigger (from the lockstep) and where it stopped; position_mm is
  // position_endstop + mm_per_step * (motor_sign (stop - trigger) + follower_sign (follower stop -
  // follower trigger)) / 2. relay_lag_steps: the most steps the follower ran after the primary
  // stopped (the relay's latency at the touch's speed), over the touches.
  int64_t start_steps = 0, follower_start_steps = 0;
  int64_t follower_trigger_steps = 0, follower_stop_steps = 0;
  int64_t relay_lag_steps = 0;
  // The encoder count at the final trigger, when the MCU reported it (report_encoder, v4): there
  // the carriage was at position_endstop.
  bool has_trigger_encoder = false;
  int64_t trigger_encoder_counts = 0;
  // Encoder-index homing: the encoder count at the index mark (the mark's own count), and the
  // index search's steps (position_mm is then where the motor stopped after the mark).
  bool has_index = false;
  int64_t index_encoder_counts = 0;
  // With a follower and report_encoder: the follower's encoder count at its relayed stop after the
  // final touch (CoreXY stall homing: the hard stop holds both belts from the trip to the stop).
  bool has_follower_encoder = false;
  int64_t follower_stop_encoder_counts = 0;
};

class HomingSequence {
 public:
  // follower_session: the follower's MCU (nullptr: the primary's); unused without a follower.
  HomingSequence(const HomingParams& params, McuSession& session,
                 McuSession* follower_session = nullptr);
  // Starts from the motor's current step position (as the host knows it) at host time now_s.
  Status start(int64_t position_steps, double now_s);
  // Advances the sequence; returns the phase after this call.
  HomingPhase poll(double now_s);
  HomingPhase phase() const { return phase_; }
  bool running() const {
    return phase_ != HomingPhase::kIdle && phase_ != HomingPhase::kDone &&
           phase_ != HomingPhase::kFailed;
  }
  // Stops a running sequence (another axis failed, the MCU faulted): no more steps are streamed
  // and the endstop is disarmed; the phase becomes kFailed with `why` in the error.
  void abort(const char* why);
  const HomingParams& params() const { return p_; }
  const std::optional<Error>& error() const { return error_; }
  const HomingResult& result() const { return result_; }
  // The host's idea of the motor's step position (follows the steps it queued and the stops).
  int64_t position_steps() const { return pos_steps_; }
  // The MCU clock of the last step this sequence queued (the MCU refuses a later batch that starts
  // before it: the owner's step stream restarts from here). INT64_MIN before any.
  int64_t last_queued_clock() const { return queued_any_ ? last_step_clock_ : INT64_MIN; }
  // The same for the follower, on its MCU's clock.
  int64_t follower_last_queued_clock() const {
    return f_queued_any_ ? f_last_step_clock_ : INT64_MIN;
  }

 private:
  struct Move {
    double d_mm = 0.0, v = 0.0, a = 0.0;  // |distance|, speed, acceleration
    int dir = 1;
    double t0 = 0.0;                    // MCU-clock seconds of its start
    double time_at(double x_mm) const;  // from t0, for 0 <= x <= d
    double duration() const;
  };
  void begin_move(double distance_mm, double speed_mm_s, double now_s);
  void stream(double now_s);
  bool move_done(double now_s, double margin_s) const;
  void arm(bool on);
  void arm_motor(McuSession& s, uint8_t motor, bool on, protocol::EndstopSource source,
                 uint8_t flags = 0);
  void on_primary_trigger(const protocol::EndstopTriggerMsg& t, double now_s);
  void on_follower_trigger(const protocol::EndstopTriggerMsg& t, double now_s);
  void after_stop(const protocol::EndstopTriggerMsg& t, double now_s);
  void set_result_at(int64_t primary_stop_steps);
  void finish_at(int64_t primary_stop_steps);
  void take_triggers(double now_s);
  void fail(std::string message);
  double mcu_s(double host_s) const;

  HomingParams p_;
  McuSession& session_;
  McuSession& fsession_;  // the follower's (session_ when it shares the MCU)
  HomingPhase phase_ = HomingPhase::kIdle;
  std::optional<Error> error_;
  HomingResult result_;
  int64_t pos_steps_ = 0;
  // The move being streamed.
  Move move_;
  int64_t move_start_steps_ = 0, move_steps_total_ = 0, move_steps_sent_ = 0;
  int64_t last_step_clock_ = 0;
  bool have_last_clock_ = false, streaming_ = false, queued_any_ = false;
  int64_t first_trigger_steps_ = 0;
  double query_sent_s_ = 0.0;
  // The follower (has_follower): its host-side position, its stream, the located start.
  int64_t f_pos_steps_ = 0, f_move_start_steps_ = 0, f_last_step_clock_ = 0;
  bool f_have_last_clock_ = false, f_queued_any_ = false;
  bool located_p_ = false, located_f_ = false;
  double wait_since_s_ = 0.0;  // kLocate / kFollowerStop started
  HomingPhase stopped_in_ = HomingPhase::kIdle;  // the touch the primary triggered in
  protocol::EndstopTriggerMsg primary_trigger_{};  // its trigger, while the follower stops
};

}  // namespace feedloop::drivers
