// The motion back end of the machine: the same stages as batch mode, split across the planner
// and servo threads.
//
//   planner thread: Interpreter -> Planner (lookahead) -> SpscQueue<PlannedMove>
//   servo thread:   SpscQueue -> JointEmitter -> StepPipeline (exact steps, compression,
//                   batches) -> BatchSink                                    (exact path)
//                   SpscQueue -> MoveTimeline -> sampled every period -> ServoControl
//                   (feedforward + PI on the encoders) -> StepPipeline       (sampled path)
//
// The exact path turns each planned move into its exact joint polynomials lead_s ahead (open
// loop, F = 1). The sampled path (DESIGN.md "Data flow": control between planner and stepgen)
// runs when the config asks for closed-loop control or a feedforward filter: every period it
// samples the plan P periods ahead (the feedforward's preview), computes the motor command
// u = F(r) + C(r - x_e) for `control_lead_s` ahead (a few periods, so the PI sees its own effect
// within a few periods) and emits the linear joint segment from the previous command to it.
//
// The planner stays at most `max_buffered_s` of motion ahead of the machine: a motion command
// waits for room before it is executed (never in the middle of a lookahead flush), so a host's
// oks follow the machine as on a Marlin printer.
//
// Time: the planner works in print time. When motion starts from rest, the servo thread anchors
// print time on the machine clock so that the first segment starts `lead_s` after now
// (mcu_time = print_time + offset); steps are generated and batches closed `lead_s` ahead of
// their execution (Klipper queues >= 100 ms ahead). When the queue runs dry and the last segment
// has been executed, the anchor is released and the next motion re-anchors.
//
// Pressure advance (planner/pressure_advance.hpp): when the first move of a motion from rest has
// K > 0, the extruder joint follows e_adv(t) instead of e(t) until the motion ends. e_adv(t)
// needs the plan up to t + smooth_time/2, so moves are taken smooth_time/2 earlier (exact path)
// or smooth_time earlier (sampled path), the motion starts smooth_time/2 later, and the extruder
// ends smooth_time/2 after the last move. With K = 0 nothing changes (the same steps).
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include "core/spsc_queue.hpp"
#include "engine/config_mapping.hpp"
#include "engine/machine.hpp"
#include "engine/servo_backend.hpp"
#include "engine/servo_control.hpp"
#include "engine/step_pipeline.hpp"
#include "engine/telemetry_tap.hpp"
#include "planner/interpreter.hpp"
#include "planner/joint_output.hpp"
#include "planner/kinematics.hpp"
#include "planner/lookahead.hpp"
#include "planner/pressure_advance.hpp"
#include "planner/sampler.hpp"

namespace feedloop::engine {

struct MotionOptions {
  double lead_s = 0.1;              // steps are queued this far ahead of execution
  size_t move_queue_capacity = 4096;
  double input_pause_flush_s = 0.05;  // flush the lookahead after this long without commands
  double max_buffered_s = 1.0;        // the planner runs at most this far ahead of the machine, so
                                      // a host's oks follow the motion (Marlin's buffer ~ 16 moves)
  double control_lead_s = 0.004;      // sampled path: commands are computed this far ahead
  double control_settle_s = 0.4;      // closed loop: the loop holds the position this long after
                                      // the plan's end (thesis Sect. 5.1: the integrator needs ~400 ms)
  size_t timeline_capacity = 8192;    // sampled path: planned moves kept for sampling
  double settle_tail_s = 0.25;        // the telemetry tap (the recorder) keeps sampling the encoders
                                      // this long after the motion ends: the carriage still settles
  // Virtual time: M400 returns only when the machine is at rest, the loop's hold after the plan
  // (control_settle_s) included. Otherwise the hold runs on at CPU speed after M400 returns, and
  // the next job's first move lands in it at a virtual instant set by the host's pace: the same
  // calibration tracked its check pattern 0.3334 or 0.3860 mm (docs/calibration.md).
  bool m400_waits_for_rest = false;
};

// Figures the servo side publishes (relaxed atomics; for status and tests).
struct MotionTelemetry {
  std::atomic<double> print_time_s{0.0};  // print time now (while anchored)
  std::atomic<uint64_t> segments{0};
  std::atomic<uint64_t> batches{0};
  std::atomic<uint64_t> anchors{0};       // motion starts from rest
  std::atomic<bool> anchored{false};
};

class MotionExecutor final : public CommandExecutor, private planner::MoveSink {
 public:
  // `batches` receives the step batches on the servo thread (an MCU session, or a counter).
  MotionExecutor(const planner::PlannerConfig& pcfg, const StepPipelineParams& sp,
                 std::shared_ptr<stepgen::BatchSink> batches, MotionOptions options = {});

  Status execute(const gcode::Command& cmd, const std::atomic<bool>& cancel) override;
  void position(double out_mm[4]) const override;
  void homed_axes(char out[4]) const override { interp_->homed_axes(out); }
  void set_extrude_guard(std::function<std::string()> guard) override {
    interp_->set_extrude_guard(std::move(guard));
  }
  planner::ObjectLabels object_labels() const override {
    std::lock_guard<std::mutex> lock(objects_mu_);
    return objects_;
  }
  void idle_tick(const std::atomic<bool>& cancel) override;
  void release_lookahead() override;
  void set_waiting_for_motion(bool waiting) override { waiting_.store(waiting); }
  void servo_cycle(int64_t now_ns, bool cancel) override;
  void servo_stopped() override { servo_stopped_.store(true, std::memory_order_release); }
  bool faulted() const override;
  bool motion_pending() const override;
  bool settling() const override { return settling_.load(std::memory_order_relaxed); }
  double take_idle_dwell_s() override { return std::exchange(idle_dwell_s_, 0.0); }
  void motion_status(MachineStatus& s) const override;
  bool may_advance_virtual(bool planner_busy) const override;
  void on_deadline_miss(int64_t now_ns, int64_t late_ns) override;
  void flush_motion(const std::atomic<bool>& cancel) override;

  // The last flush's stop (Machine::flush), as the servo thread commanded it. Read after
  // flush_motion() returned.
  struct StopFigures {
    bool warped = false;             // sampled path: the plan was slowed to a stop along the path
    double speed_mm_s = 0.0;         // path speed where the stop began
    double decel_mm_s2 = 0.0;        // the smallest deceleration the limits allowed on the way
    double path_mm = 0.0;            // XYZ path length from the stop's start to the rest point
    double request_s = 0.0;          // host time the servo thread took the request
    double begin_s = 0.0;            // host time of the first slowed sample (request + the lead)
    double rest_s = 0.0;             // host time the command reached the rest point
    uint64_t moves_dropped = 0;      // planned moves never executed
    double position_mm[4] = {0, 0, 0, 0};  // where the plan stopped (machine coordinates)
  };
  StopFigures last_stop() const { return stop_figures_; }
  // True once the planner thread has asked the servo thread to abort the running G28 (a cancel or a
  // flush), until the next G28. Any thread.
  // True while a flush's stop waits for the servo thread: asked and released by the planner thread
  // (flush_motion), not yet taken. Any thread.
  bool homing_abort_requested() const { return homing_abort_.load(std::memory_order_acquire); }
  bool stop_waits_for_servo() const {
    return stop_req_.load(std::memory_order_acquire) == kStopRequested &&
           stop_released_.load(std::memory_order_acquire);
  }

  // The MCUs behind the batch sink (engine/mcu_bridge.hpp); set before the servo thread starts.
  // Each servo cycle then services it first, takes its clock estimates for step timing, waits
  // for ready() before motion starts from rest, and stops motion on fault().
  void set_backend(ServoBackend* backend) { backend_ = backend; }
  const SharedHeaterPorts* heater_ports() const override {
    return backend_ != nullptr ? backend_->heater_ports() : nullptr;
  }
  // The control law: with one set, the servo cycle takes the sampled path. Before start.
  void set_control(std::unique_ptr<ServoControl> control);
  // An observer of planned moves, servo samples and events (the recorder; benchmarks). Before start.
  void set_telemetry(TelemetryTap* tap) { tap_ = tap; }

  // One-thread runs (engine/sim_run.cpp, test rigs): the caller's servo cycle, run by a command
  // that waits for the machine (G28 through the endstops, M400) instead of sleeping: the same
  // thread drives both stages there. Before start.
  void set_inline_driver(std::function<void()> cycle) { inline_driver_ = std::move(cycle); }

  const MotionTelemetry& telemetry() const { return telemetry_; }
  const StepPipeline& steps() const { return steps_; }  // servo thread owns it
  uint64_t moves() const { return interp_->moves(); }
  // Device loop: the MCU tick on which the latest motion's first command sample of `joint` falls
  // (its clock frame, motion_executor.hpp); 0 before any. Any thread.
  int64_t motion_start_clock(int joint) const {
    return motion_start_clock_[static_cast<size_t>(joint)].load(std::memory_order_relaxed);
  }
  // Device loop: how often a motion's clock frame was replaced mid-motion (the clock sync's
  // estimate moved more than kClockFrameTolerance_s). Servo thread's figure, read relaxed.
  uint64_t clock_frame_refreshes() const { return clock_frame_refreshes_.load(std::memory_order_relaxed); }

 private:
  void on_move(const planner::PlannedMove& m) override;
  void on_event(const planner::PlannerEvent& e) override;
  void queue_move(const planner::PlannedMove& m);  // planner thread: into the servo thread's queue
  void motors_off(const gcode::Command& cmd, const std::atomic<bool>& cancel);  // M18/M84
  // Planner thread: blocks until the servo thread has executed print time `t_s`.
  void wait_print_time(double t_s, const std::atomic<bool>& cancel);
  // Print time the machine is executing now (or where it will restart from rest).
  double executing_print_time_s() const;
  // Planner thread: blocks while more than max_buffered_s of motion is queued.
  void wait_for_room(const std::atomic<bool>& cancel);
  // Planner thread: lets the machine run for a moment (the inline driver's cycle, or a sleep).
  void pause_for_machine();
  std::function<void()> inline_driver_;

  // G28 through the endstops (docs/homing.md): the planner thread waits until the motion before
  // it has ended, asks the servo thread (homing_req_) and waits for the outcome; the servo thread
  // runs the homing on the backend (the MCUs) with the step stream paused, then re-bases the step
  // generators (resync) at the homed positions the interpreter continues from.
  bool homes_through_endstops() const;
  Status home(const gcode::Command& cmd, const std::atomic<bool>& cancel);
  void homing_cycle(double now_s, bool cancel);  // servo thread
  void after_homing();                           // servo thread
  enum HomingRequest : int {
    kNoHoming = 0,
    kHomingRequested,
    kHomingRunning,
    kHomingDone,
    kHomingFailed
  };
  std::atomic<int> homing_req_{kNoHoming};
  // home() saw its command interrupted (a flush: a job's cancel, M524; or an emergency stop): the
  // servo thread aborts the homing on the MCUs, and the G28 ends as failed, the axes unhomed.
  std::atomic<bool> homing_abort_{false};
  // The servo thread has ended (the machine stopping): no cycle will answer a homing request.
  std::atomic<bool> servo_stopped_{false};
  std::atomic<unsigned> homing_mask_{0};
  std::array<double, kJoints> homed_joint_mm_{};        // servo thread writes before kHomingDone
  std::array<double, 3> homing_shift_mm_{};            // (CoreXY) likewise: unhomed axes moved
  char homing_error_[192] = {};                         // servo thread writes before kHomingFailed
  std::array<std::atomic<double>, 3> homed_axis_mm_{};  // status: each axis's last homed position
  std::atomic<uint64_t> homings_{0};

  planner::PlannerConfig pcfg_;
  MotionOptions options_;
  std::unique_ptr<planner::Kinematics> kin_;
  planner::Planner planner_;
  double idle_dwell_s_ = 0.0;
  std::atomic<unsigned> motors_off_req_{0};  // M18/M84's joints, for the servo thread to switch off
  unsigned motors_off_mask_ = 0;             // servo thread: the joints whose drivers are off
  double motors_off_sent_s_ = 0.0;  // servo thread: when the last M84 went out  // planner thread:
                                    // a G4's time with no motion to put it in
  std::unique_ptr<planner::Interpreter> interp_;
  planner::JointEmitter emitter_;
  SpscQueue<planner::PlannedMove> queue_;
  std::shared_ptr<stepgen::BatchSink> batches_;
  StepPipeline steps_;  // servo thread

  // planner thread
  const std::atomic<bool>* cancel_ = nullptr;
  double wait_until_s_ = -1.0;  // set by a moves_done event during execute()
  std::atomic<double> idle_base_s_{0.0};  // print time where motion restarts from rest
  std::chrono::steady_clock::time_point last_command_{};
  std::atomic<double> planned_end_s_{0.0};  // end of the last segment handed to the servo
  std::atomic<uint64_t> pushed_{0};
  std::atomic<uint64_t> moves_emitted_{0};
  // The interpreter's object labels, copied after each object label command (planner thread) for
  // object_labels() on other threads.
  mutable std::mutex objects_mu_;
  planner::ObjectLabels objects_;
  std::atomic<bool> waiting_{false};  // the planner thread waits for the machine (M400, room)
  std::atomic<size_t> planner_queued_{0};  // mirror of planner_.queued() for the other threads

  // servo thread
  ServoBackend* backend_ = nullptr;
  // Joint positions restart from the next move's start: at power-on (a delta's carriages are not
  // at 0) and after a fault (the steps queued then were not all executed).
  bool resync_ = true;
  void drop_queued_moves();
  // Flush (Machine::flush): the planner thread asks (stop_req_), releases the lookahead's moves
  // (each motion ends at rest) and says so (stop_released_); the servo thread slows the plan to a
  // stop along the path (sampled path: the plan's time runs at a rate lambda <= 1 chosen so that
  // the path speed lambda v falls at the deceleration the limits allow), drops the moves after the
  // rest point, and reports the rest point (kStopDone), from which the interpreter continues. The
  // exact path (open loop, no control law) has its steps computed lead_s ahead from whole moves:
  // it runs the released moves to their end (the machine queue is still dropped).
  enum StopRequest : int { kNoStop = 0, kStopRequested, kStopRunning, kStopDone };
  std::atomic<int> stop_req_{kNoStop};
  std::atomic<bool> stop_released_{false};
  bool stop_warping_ = false, stop_frozen_ = false;  // servo thread
  double stop_cap_mm_s_ = 0.0;     // the path speed allowed now
  double stop_lead_plan_s_ = 0.0;  // plan time at the feedforward's input (the preview front)
  double stop_start_plan_s_ = 0.0;
  double stop_end_s_ = 0.0;        // servo time the motion ends (the rest point, the hold after)
  std::vector<double> stop_tau_;   // plan time of each command sample (ring by sample number)
  bool stop_pos_valid_ = false;
  planner::Vec4 stop_pos_mm_{};
  StopFigures stop_figures_{};
  void begin_stop(double now_s);   // servo thread
  double stop_step(double t_s);    // servo thread: one warped sample; the preview front's plan time
  void finish_stop();              // servo thread, at rest
  bool reference_plan(double plan_s, control::FeedforwardInput& out) const;
  planner::PlannedMove current_;  // the move most recently handed to step generation
  // Pressure advance (servo thread): active for the current motion from rest.
  planner::PressureAdvance pa_;
  bool pa_active_ = false;
  double pa_base_shift_s_ = 0.0;  // sampled path: pa time = servo time - this (holds pause it)
  double pa_half_window_s() const { return pa_active_ ? pa_.half_window_s() : 0.0; }
  void pa_restart(const planner::PlannedMove& first);
  // The joints but the extruder go to step generation; the extruder's come from pa_.
  struct NoExtruder final : planner::JointSink {
    planner::JointSink* next = nullptr;
    void on_joint_segment(int joint, const JointSegment& s) override {
      if (joint != 3) next->on_joint_segment(joint, s);
    }
  } no_extruder_;
  // The planner thread's pressure advance (M900 / SET_PRESSURE_ADVANCE), for the status.
  std::atomic<double> pa_advance_s_{0.0}, pa_smooth_time_s_{0.0};
  std::atomic<double> speed_factor_{1.0}, flow_factor_{1.0};   // the interpreter's M220 / M221
  std::atomic<double> feedrate_mm_s_{0.0};                     // its last F
  std::atomic<bool> relative_xyz_{false}, relative_e_{false};  // and its G91 / M83
  std::atomic<bool> inches_{false};                            // and its G20
  // Sampled path (servo thread).
  void sampled_cycle(double now_s);
  void start_sampled(const planner::PlannedMove& first, double now_s);
  void resync_to(const planner::PlannedMove& front);
  bool reference(double t_s, control::FeedforwardInput& out) const;
  control::FeedforwardInput input_at(const planner::CartesianSample& c) const;
  void publish_sample(double now_s, double print_time_s, const control::JointArray& desired_mm,
                      const control::JointArray& command_mm, const std::array<double, 3>& nozzle_mm);
  std::atomic<uint64_t> lost_step_events_{0};
  std::atomic<uint64_t> late_cycles_{0};
  // e_t from the encoders (servo thread writes; status reads relaxed).
  std::atomic<double> e_t_sum_mm_{0.0}, e_t_max_mm_{0.0};
  std::atomic<uint64_t> e_t_samples_{0};
  std::array<double, 4> last_e_mm_{};  // servo thread: each joint's latest r - y (e_t's terms)
  // Servo thread, while motion runs: e_t at one encoder sample of `joint` (its reading in the
  // steps' frame, taken at mcu_clock).
  void e_t_at_encoder_sample(int joint, int64_t mcu_clock, double enc_mm);
  void add_e_t_sample();               // servo thread: e_t of last_e_mm_ into the counters
  std::array<bool, 4> has_e_{};
  // Each joint's step counter as the servo thread left it (M114's Count), published per cycle.
  std::array<std::atomic<int64_t>, 4> step_count_{};
  std::unique_ptr<ServoControl> control_;
  bool device_loop_ = false;  // some joint's PI runs on its MCU: r(t) is streamed to it
  // How far ahead the sampled path commands: the host loop's delay, or with the device loop as
  // far ahead as the steps (the MCUs must hold r(t) for a stall of that length).
  // The device stops when r's queue ends within its 20 ms horizon margin, and a knot may wait 10 ms
  // in the compressor: the lead covers that on top of lead_s, so a stall up to lead_s is harmless.
  static constexpr double kDeviceHorizonSlack_s = config::kDeviceTargetMarginMs * 1e-3;
  double command_lead_s() const {
    return device_loop_ ? std::max(options_.control_lead_s, options_.lead_s + kDeviceHorizonSlack_s)
                        : options_.control_lead_s;
  }
  double last_cycle_s_ = 0.0;
  std::unique_ptr<planner::MoveTimeline> timeline_;
  struct Sample {  // one command sample, kept for the feedback comparison
    double t_s = 0.0;
    double plan_s = 0.0;  // its plan (print) time: t_s less the plan's shift when it was commanded
    control::JointArray r_mm{}, u_mm{}, u_ff_mm{};
    control::JointArray load_mm{};  // the feedforward's load share of u (friction, weight)
    std::array<double, 3> nozzle_mm{};
  };
  std::vector<Sample> history_;  // ring, indexed by sample number
  uint64_t sample_no_ = 0;       // samples emitted since the anchor
  uint64_t model_next_ = 0;
  double model_t_s_ = 0.0;       //   and the servo time it has advanced to
  bool host_feedback(double now_s, uint64_t n_enc, double enc_time_s,
                     const control::JointArray& enc, const std::array<bool, 4>& fresh);      // host loop: the next sample the lost-step model advances over
  bool prime_pending_ = false;   // the feedforward's preview is to be filled (motion start)
  double next_sample_s_ = 0.0;   // servo time of the last command sample (segment end)
  double plan_shift_s_ = 0.0;    // servo time - plan (print) time: grows when a move arrives
                                 // while the loop holds the position after the plan's end
  // The device loop's clock frame (docs/decisions.md, "One motion, one clock frame"): from a
  // motion's start the steps and r(t) go through these servo time -> MCU tick maps, taken from
  // the clock sync at the start (its first sample on a whole tick) and replaced only when the
  // live estimate has moved more than kClockFrameTolerance_s away from them. So a host stall or a
  // late clock reply does not move a single step tick; the MCUs' own clocks pace the motion.
  static constexpr double kClockFrameTolerance_s = 20e-6;
  std::array<std::atomic<int64_t>, kJoints> motion_start_clock_{};
  std::array<stepgen::TickMap, kJoints> motion_maps_{};
  bool motion_maps_held_ = false;
  std::atomic<uint64_t> clock_frame_refreshes_{0};  // written by the servo thread only
  stepgen::TickMap frame_through(const stepgen::TickMap& live, double t_s) const;
  void hold_clock_frame(double t0_s);
  void refresh_clock_frame(double t_s);
  control::JointArray encoder_offset_mm_{};   // joint position - encoder reading, set at resync
  control::JointArray last_command_mm_{};     // the motor command the steps follow (sampled path)
  std::array<unsigned long long, 4> encoder_reports_seen_{};
  // After the motion ends: the last sample, republished with fresh encoders until settle_end_s_.
  void run_cycle(double now_s, bool cancel);  // servo_cycle() before the settling tail
  void publish_step_counts();  // each joint's step counter, for M114 and the status
  void publish_settling(double now_s, bool was_anchored);
  ServoSample last_sample_{};
  double settle_end_s_ = 0.0;
  std::atomic<bool> settling_{false};
  TelemetryTap* tap_ = nullptr;
  std::atomic<bool> control_fault_{false};
  char control_fault_text_[160] = {};
  double offset_s_ = 0.0;
  double executed_end_s_ = 0.0;
  std::atomic<uint64_t> popped_{0};
  MotionTelemetry telemetry_;
};

}  // namespace feedloop::engine
