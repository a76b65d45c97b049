// The machine: one pipeline for real time (the daemon) and virtual time (tests, batch, replay).
//
//   I/O thread ──try_submit──> command queue ──> planner thread ──> executor (interpreter,
//   lookahead, joint segments) ──> servo thread (every period: control, step batches)
//
// Threads (DESIGN.md "Threads and time"): the caller's I/O thread submits commands and polls
// events; the planner thread executes commands in order and may block (M109, full queues); the
// servo thread runs at a fixed period with absolute-deadline sleeps, allocates nothing, locks
// nothing, and counts its deadline misses. Status is published through seqlocks.
#pragma once

#include <atomic>
#include <cmath>  // NAN
#include <condition_variable>
#include <cstdint>
#include <cstring>  // memcpy
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "core/clock.hpp"
#include "core/result.hpp"
#include "core/spsc_queue.hpp"
#include "engine/device_loop_telemetry.hpp"
#include "engine/latency_histogram.hpp"
#include "engine/link_telemetry.hpp"
#include "engine/seqlock.hpp"
#include "engine/shared_heater_port.hpp"
#include "engine/thermal_loop.hpp"
#include "gcode/command.hpp"
#include "planner/object_labels.hpp"

namespace feedloop::engine {

enum class MachineState : uint8_t { kIdle, kBusy, kError, kEmergencyStopped, kStopped };
const char* to_string(MachineState s);

// A snapshot for status queries (JSON API, M105, M114). Trivially copyable.
struct MachineStatus {
  MachineState state = MachineState::kIdle;
  double pos_mm[4] = {0, 0, 0, 0};  // X Y Z E of the last executed command (planned position)
  char homed_axes[4] = {};           // "" .. "xyz": homed since the last G28 (M18/M84 clear it)
  // Homing through the endstops (docs/homing.md): each axis's position from its last homing (NaN:
  // never homed through a switch), the G28s done that way, whether one runs now, and each X Y Z
  // joint's switch as last queried (M119: -1 none or unknown, 0 open, 1 triggered; min or max end).
  double homed_position_mm[3] = {NAN, NAN, NAN};
  uint64_t homings = 0;
  bool homing = false;
  int8_t endstop[3] = {-1, -1, -1};
  bool endstop_at_max[3] = {false, false, false};
  double hotend_c = 0, hotend_target_c = 0, bed_c = 0,
         bed_target_c = 0;  // the first T and B heater
  // The extruding hotend (T0) must be at or above this to extrude (min_extrude_temp, M302 S);
  // 0: any temperature (M302 P1, or no hotend to check). See can_extrude().
  double min_extrude_temp_c = 0;
  // Heaters and fans (engine/thermal_loop.hpp); temp_report: Marlin's "T:210.0 /210.0 B:.. @:..
  // B@:..".
  HeaterStatus heaters[ThermalLoop::kMaxHeaters] = {};
  int num_heaters = 0;
  FanStatus fans[ThermalLoop::kMaxFans] = {};
  int num_fans = 0;
  char temp_report[160] = {};
  uint32_t queue_depth = 0;
  uint32_t queue_capacity = 0;
  uint64_t commands_executed = 0;
  uint64_t commands_rejected = 0;
  uint64_t commands_flushed = 0;  // queued commands dropped by a flush (cancel), not run
  uint64_t flushes = 0;           // flushes done (Machine::flush)
  // Motion (filled by the executor)
  bool moving = false;           // print time is anchored on the machine clock
  double print_time_s = 0.0;     // print time being executed now
  double planned_until_s = 0.0;  // end of the last planned segment
  double pressure_advance_s = 0.0;              // M900 K / SET_PRESSURE_ADVANCE, as last set
  double pressure_advance_smooth_time_s = 0.0;  // its smoothing window
  double speed_factor = 1.0, flow_factor = 1.0;  // M220 S / 100, M221 S / 100, as last set
  double feedrate_mm_s = 0.0;                    // the last F (before M220's factor)
  bool absolute_coordinates = true, absolute_extrude = true;  // G90 / G91, M82 / M83
  bool inches = false;                                        // G20 (G21: false)
  uint64_t moves_planned = 0;
  uint64_t segments_queued = 0;   // joint segments waiting for the servo thread
  uint64_t motion_starts = 0;     // times motion started from rest
  uint64_t lost_step_events = 0;  // closed loop: slips detected (and made up)
  // Tracking error e_t measured from the encoders: |r - x_enc| over the joints with an encoder
  // (x and y on the gantry: the thesis's e_t), at each fresh report while motion runs.
  double tracking_error_mean_mm = 0.0, tracking_error_max_mm = 0.0;
  uint64_t tracking_error_samples = 0;
  uint64_t late_cycles = 0;  // sampled path: the plan paused for a late servo cycle
  double encoder_mm[4] = {0, 0, 0,
                          0};    // latest encoder reading per joint from the MCUs (NaN: none)
  uint64_t encoder_samples = 0;  // encoder samples received from the MCUs
  int64_t step_count[4] = {0, 0, 0, 0};   // each joint's step counter (the executor steps them)
  bool has_step_count = false;            // false: this executor makes no steps
  LinkTelemetrySet links;                 // each MCU link (frames, retransmissions, round trips)
  DeviceLoopTelemetrySet device_loops{};  // each joint's device loop (e, y, correction, tick cost)
  char last_error[192] = {};
};

// Whether an extruding move would pass the cold-extrusion check now (Machine::why_not_extrude
// refuses it otherwise): a hotend without a reading yet (NaN) is cold.
inline bool can_extrude(const MachineStatus& s) {
  return s.min_extrude_temp_c <= 0.0 || s.hotend_c >= s.min_extrude_temp_c;
}

// What the servo thread publishes every cycle.
struct ServoStatus {
  uint64_t cycles = 0;
  uint64_t deadline_misses = 0;
  int64_t last_wake_ns = 0;
  LatencyHistogram latency;
};

// The machine's motion back end. Planner-thread side: execute() runs commands in order and
// idle_tick() is called when no command is waiting. Servo-thread side: servo_cycle() runs once
// per period and must be real-time safe (no allocation, no locks, no blocking). Implementations:
// PositionExecutor (positions only, no motion) and MotionExecutor (interpreter, lookahead, joint
// segments, step pipeline).
class CommandExecutor {
 public:
  virtual ~CommandExecutor() = default;
  // Executes one command. A rejected command must change no state. May block; must return
  // promptly once `cancel` becomes true.
  virtual Status execute(const gcode::Command& cmd, const std::atomic<bool>& cancel) = 0;
  // Planned position X Y Z E after the last executed command.
  virtual void position(double out_mm[4]) const = 0;
  // The homed axes, lower-case in xyz order ("" .. "xyz"; out holds 4 chars). An executor without
  // a homing state moves anywhere: "xyz".
  virtual void homed_axes(char out[4]) const { std::memcpy(out, "xyz", 4); }
  // Planner thread, when idle: e.g. release the lookahead's tail after a pause in the input.
  virtual void idle_tick(const std::atomic<bool>& /*cancel*/) {}
  // Planner thread, when a wait begins (M109/M190/M303, G4 at rest): the moves the lookahead
  // holds go to the motion now, as a pause in the input would release them (Klipper flushes its
  // lookahead before a heater wait too). Held, they waited for the wait's end in real time, and
  // in virtual time the wait waited for them (no time passed: a job started right after a move
  // never heated).
  virtual void release_lookahead() {}
  // Planner thread, virtual time, while such a wait has motion still to run: the servo side may
  // advance the clock through that motion (nothing more comes from the planner meanwhile), as it
  // does for M400.
  virtual void set_waiting_for_motion(bool /*waiting*/) {}
  // Servo thread, once per period. RT-safe.
  virtual void servo_cycle(int64_t /*now_ns*/, bool /*cancel*/) {}
  // Servo thread, once, after its last cycle (the machine stopping): a request that waits for a
  // servo cycle's answer (a homing) must not wait any longer.
  virtual void servo_stopped() {}
  // Servo thread, RT-safe: the cycle at now_ns woke late_ns after its deadline (> one period).
  virtual void on_deadline_miss(int64_t /*now_ns*/, int64_t /*late_ns*/) {}
  // True while moves are queued anywhere or being executed. Any thread.
  virtual bool motion_pending() const { return false; }
  // True while the motion has ended but the telemetry still follows the carriage as it settles
  // (the flight recorder keeps its encoder samples). Not motion: M400 does not wait for it; the
  // machine is idle only after it. Any thread.
  virtual bool settling() const { return false; }
  // True while a fault (an MCU gone, an implausible encoder) has stopped the motion: the motion
  // still queued will not run, so the machine is not busy but in error. Any thread.
  virtual bool faulted() const { return false; }
  // Virtual time only: may the servo thread advance time now? It must not run past the motion
  // the planner is still producing (that would cut the motion into pieces), but must advance
  // when the planner has nothing more to give. `planner_busy`: a command is queued or executing.
  virtual bool may_advance_virtual(bool planner_busy) const {
    return !planner_busy || motion_pending();
  }
  // Fills the motion fields of a status snapshot. Any thread.
  virtual void motion_status(MachineStatus& /*s*/) const {}
  // Any thread: the G-code's object labels (Klipper's exclude_object status; a copy taken when an
  // object label command ran). Default: none.
  virtual planner::ObjectLabels object_labels() const { return {}; }
  // Planner thread, before start(): asked before any move that moves E (the interpreter's
  // ExtrudeGuard): why the extruder may not move now, "" when it may. Default: not asked.
  virtual void set_extrude_guard(std::function<std::string()> /*guard*/) {}
  // The heater ports of the motion MCUs that drive heaters too (make_thermal_loop's `ports`;
  // engine/shared_heater_port.hpp); nullptr: none. Fixed at construction.
  virtual const SharedHeaterPorts* heater_ports() const { return nullptr; }
  // Planner thread, after execute(): the time of a dwell (G4) the executor could not put into its
  // motion (the machine was at rest, or homing), which the machine then waits on its own clock;
  // 0 when none. Taking it clears it.
  virtual double take_idle_dwell_s() { return 0.0; }
  // Planner thread, for Machine::flush: the motion planned so far stops as soon as the limits
  // allow (a controlled deceleration along the path, no lost steps), the rest of it is dropped,
  // and the position continues from where the machine stopped. Returns once the machine is at
  // rest, or early when `cancel` becomes true (the machine stopping). Default: the motion ends
  // as planned (an executor without a step stream has nothing to stop).
  virtual void flush_motion(const std::atomic<bool>& /*cancel*/) {}
};

struct MachineOptions {
  double servo_rate_hz = 1000.0;
  size_t command_queue_capacity = 64;
  int realtime_priority = 80;  // SCHED_FIFO priority of the servo thread (0 = do not try)
  bool lock_memory = true;
  // No E move while the hotend (T0) is colder (C; 0: none); M302 changes it. Only with heaters.
  double min_extrude_temp_c = 170.0;
};

// A finished command, reported through the completion callback on the planner thread.
struct CommandDone {
  uint64_t ticket = 0;
  Status status;
  // Lines the command reports to its host before its answer (M303's PID values, M302's state),
  // '\n'-separated, without the trailing newline; empty for most commands.
  std::string report;
};

class Machine {
 public:
  using DoneCallback = std::function<void(CommandDone)>;

  Machine(MachineOptions options, Clock& clock, std::unique_ptr<CommandExecutor> executor);
  ~Machine();
  Machine(const Machine&) = delete;
  Machine& operator=(const Machine&) = delete;

  // Called on the planner thread for every command, in order. Set before start().
  void set_done_callback(DoneCallback cb) { on_done_ = std::move(cb); }
  // Heaters and fans (engine/thermal_config.hpp make_thermal_loop). Set before start(); without
  // one, M104/M109/M140/M190 are accepted and do nothing (a machine without heaters).
  void set_thermal(std::unique_ptr<ThermalLoop> thermal);
  ThermalLoop* thermal() { return thermal_.get(); }

  // Starts the planner and servo threads. Warnings (no SCHED_FIFO, no mlockall) are returned
  // through `warnings` and do not fail the start.
  Status start(std::string* warnings = nullptr);
  // Stops motion safely: cancels queued commands, stops the threads, waits for them.
  void stop();

  // Batch mode (no threads: never start()ed): runs one command on the calling thread through the
  // planner stage's own dispatch (planner_main), so batch, virtual and real time share it. There
  // is no servo stage: an executor that needs one (MotionExecutor) must be run with start().
  Status execute_inline(const gcode::Command& cmd);

  // One-thread runs (never start()ed; run_simulated: deterministic virtual time): the caller
  // interleaves execute_inline() with one servo period at a time, at its own virtual now_ns
  // (a gap of more than a period counts as deadline misses, as on the clock), and lets the
  // planner stage do its idle work (release the lookahead's tail).
  Status servo_cycle_inline(int64_t now_ns);
  void idle_tick_inline();

  // I/O thread only. Returns false (and keeps `cmd`) when the queue is full.
  bool try_submit(uint64_t ticket, const gcode::Command& cmd);
  // Marlin's M108 (break and continue; its emergency parser takes it ahead of the queue): a heater
  // wait running now (M109, M190) ends at once, its target kept. Nothing else. Any thread.
  void break_heater_wait() { break_heater_wait_.store(true); }
  // Any thread. Latches kEmergencyStopped; queued commands are cancelled.
  void emergency_stop(const std::string& reason);
  // Any thread: a cancel at once, without the emergency stop's latch (Marlin's M524 / Klipper's
  // CANCEL_PRINT as users expect them). The command executing now returns (a wait for a
  // temperature or for the machine ends), every command still in the queue is dropped (its
  // completion reports "dropped by a flush"; counted in commands_flushed, not rejected), and the
  // executor stops its planned motion in a controlled deceleration (CommandExecutor::
  // flush_motion). With `heaters_off` every heater's target is 0 at once, on the calling thread,
  // and again once the queue is drained (a heater command already on its way cannot undo it).
  // Commands submitted after the drain run normally once the machine is at rest (a cancel's park
  // moves). The machine stays usable: no latch, no homing lost.
  void flush(bool heaters_off);
  // I/O thread: a source that has more commands ready (a print job reading its file) says so.
  // In virtual time the planner then keeps its lookahead while the input is late (the wall-clock
  // input pause and the running-dry release wait for the source instead): the clock does not run
  // while the source is descheduled, so where the moves stop depends on the file alone, not on
  // how busy the host is (docs/decisions.md, "Virtual time waits for a print job's input"). On the
  // real clock nothing changes: the motion must not starve for a late reader.
  void set_input_coming(bool coming) { input_coming_.store(coming, std::memory_order_release); }
  // True from flush() until the machine is at rest and the queue drained.
  bool flushing() const { return flush_requested_.load() || flush_running_.load(); }

  // Fault injection (the real-time lateness test, `docs/decisions.md` "Host stalls"): the planner
  // and servo threads each sleep `duration_ns` at their next turn, as a host that is descheduled
  // does (with simulated MCUs the servo thread is also the link's I/O, so that stops too). Any
  // thread; a second request before the first is taken replaces it.
  void inject_stall(int64_t duration_ns);

  MachineStatus status() const;
  // Any thread: the objects the G-code labelled, the excluded ones, the current one.
  planner::ObjectLabels object_labels() const {
    return executor_ ? executor_->object_labels() : planner::ObjectLabels{};
  }
  ServoStatus servo_status() const { return servo_status_.load(); }
  // True while the servo thread completed a cycle within the last 100 periods and no fatal
  // error is latched: what the systemd watchdog pets on.
  bool healthy() const;
  // No command queued or executing.
  bool idle() const;
  double servo_period_s() const { return 1.0 / options_.servo_rate_hz; }

 private:
  struct Queued {
    uint64_t ticket = 0;
    gcode::Command cmd;
  };
  void planner_main();
  void servo_main();
  void servo_tick(ServoStatus& st, int64_t wake_ns, int64_t late_ns, int64_t period_ns);
  Status dispatch(const gcode::Command& cmd);  // the planner stage: machine commands or executor
  Status execute_machine_command(const gcode::Command& cmd);  // heaters, fans, waits
  bool is_machine_command(const gcode::Command& cmd) const;
  // Waits until the heater's temperature is reached (M109/M190) or the autotune ends (M303):
  // in virtual time with nothing moving, the wait itself advances the clock.
  // Waits on the machine's clock (virtual time: advanced by the wait while nothing moves) until
  // done(now) or until_s; `what` names the wait in the error when it is cancelled.
  Status wait_for(const std::function<bool(double now_s)>& done,
                  const char* what = "wait for temperature",
                  double until_s = std::numeric_limits<double>::infinity());
  void thermal_step();  // runs the thermal loop to now; a fault stops the machine
  void thermal_main();
  void on_thermal_fault(const std::string& message);
  void publish_status();
  void fill_thermal(MachineStatus& s) const;
  void set_error(const std::string& message);

  MachineOptions options_;
  Clock& clock_;
  std::unique_ptr<CommandExecutor> executor_;
  DoneCallback on_done_;

  SpscQueue<Queued> queue_;
  std::mutex wake_mutex_;  // protects nothing but the planner's sleep
  std::condition_variable wake_cv_;

  std::atomic<bool> stopping_{false};
  // Virtual time, a heater wait while the heaters' messages travel on the motion MCUs' sessions
  // (the executor's heater_ports()): the servo thread, which alone services those sessions, runs
  // the wait's time period by period up to here (ns); 0: no such wait.
  std::atomic<int64_t> virtual_wait_until_ns_{0};
  bool servo_carries_heaters_ = false;  // set_thermal(): the thermal loop uses heater ports
  std::atomic<int64_t> planner_stall_ns_{0}, servo_stall_ns_{0};  // inject_stall, not yet taken
  std::atomic<bool> input_coming_{false};                         // set_input_coming
  std::atomic<bool> cancel_{false};     // latched: emergency stop, stop()
  std::atomic<bool> break_heater_wait_{false};  // M108 (break_heater_wait)
  std::atomic<bool> interrupt_{false};  // the command executing returns: cancel_ or a flush
  std::atomic<bool> flush_requested_{false}, flush_running_{false}, flush_heaters_off_{false};
  std::atomic<uint64_t> flushed_{0}, flushes_{0};
  void run_flush();  // planner thread
  std::atomic<bool> estop_{false};
  std::atomic<bool> executing_{false};
  std::atomic<uint64_t> executed_{0};
  std::atomic<uint64_t> rejected_{0};

  std::unique_ptr<ThermalLoop> thermal_;
  std::thread thermal_thread_;
  std::string command_report_;  // planner thread: the running command's report (CommandDone)
  // Planner thread: M302 S sets the temperature, P1 allows cold extrusion (Marlin's M302).
  double min_extrude_temp_c_ = 170.0;
  bool cold_extrusion_allowed_ = false;
  std::string why_not_extrude() const;  // the executor's extrude guard (planner thread)
  Seqlock<MachineStatus> status_;
  Seqlock<ServoStatus> servo_status_;
  ServoStatus inline_servo_;  // the caller's, in one-thread runs
  std::atomic<int64_t> servo_last_cycle_ns_{0};

  std::mutex error_mutex_;  // protects last_error_
  std::string last_error_;

  std::thread planner_thread_;
  std::thread servo_thread_;
  bool started_ = false;
};

}  // namespace feedloop::engine
