#include "engine/machine.hpp"

#include <system_error>

#include <algorithm>  // std::min
#include <chrono>     // wait_for
#include <cmath>      // isnan
#include <cstdio>     // snprintf
#include <thread>
#include <utility>  // exchange

#include "engine/realtime.hpp"

namespace feedloop::engine {

const char* to_string(MachineState s) {
  switch (s) {
    case MachineState::kIdle:
      return "idle";
    case MachineState::kBusy:
      return "busy";
    case MachineState::kError:
      return "error";
    case MachineState::kEmergencyStopped:
      return "emergency_stopped";
    case MachineState::kStopped:
      return "stopped";
  }
  return "unknown";
}

Machine::Machine(MachineOptions options, Clock& clock, std::unique_ptr<CommandExecutor> executor)
    : options_(options),
      clock_(clock),
      executor_(std::move(executor)),
      queue_(options.command_queue_capacity),
      min_extrude_temp_c_(options.min_extrude_temp_c) {
  publish_status();
}

void Machine::set_thermal(std::unique_ptr<ThermalLoop> thermal) {
  thermal_ = std::move(thermal);
  const SharedHeaterPorts* ports = executor_ ? executor_->heater_ports() : nullptr;
  servo_carries_heaters_ = thermal_ && ports != nullptr && !ports->empty();
  if (thermal_) thermal_->start(seconds_from_ns(clock_.now_ns()));
  if (thermal_ && executor_) executor_->set_extrude_guard([this] { return why_not_extrude(); });
  publish_status();
}

Machine::~Machine() {
  stop();
}

Status Machine::start(std::string* warnings) {
  if (started_) return Error{"machine already started"};
  if (!(options_.servo_rate_hz >= 100.0 && options_.servo_rate_hz <= 20000.0))
    return Error{"servo rate must be within 100..20000 Hz"};
  started_ = true;
  std::string warn;
  if (options_.lock_memory && !clock_.is_virtual()) {
    if (Status s = lock_memory(); !s) warn += s.error().message + "\n";
  }
  std::atomic<bool> rt_done{false};
  std::string rt_warning;
  try {
    planner_thread_ = std::thread([this] { planner_main(); });
    if (thermal_) thermal_thread_ = std::thread([this] { thermal_main(); });
    servo_thread_ = std::thread([this, &rt_done, &rt_warning] {
      if (options_.realtime_priority > 0 && !clock_.is_virtual()) {
        if (Status s = make_thread_realtime(options_.realtime_priority); !s)
          rt_warning = s.error().message + "\n";
      }
      rt_done.store(true, std::memory_order_release);
      servo_main();
    });
  } catch (const std::system_error& e) {  // no thread: out of memory or a resource limit
    stopping_.store(true);
    wake_cv_.notify_all();
    if (planner_thread_.joinable()) planner_thread_.join();
    if (thermal_thread_.joinable()) thermal_thread_.join();
    started_ = false;
    return Error{std::string("cannot start the machine's threads: ") + e.what()};
  }
  while (!rt_done.load(std::memory_order_acquire)) std::this_thread::yield();
  warn += rt_warning;
  if (warnings) *warnings = warn;
  return Status::Ok();
}

void Machine::stop() {
  if (!started_) return;
  cancel_.store(true);
  interrupt_.store(true);
  stopping_.store(true);
  wake_cv_.notify_all();
  if (planner_thread_.joinable()) planner_thread_.join();
  if (servo_thread_.joinable()) servo_thread_.join();
  if (thermal_thread_.joinable()) thermal_thread_.join();
  if (thermal_) thermal_->all_off(seconds_from_ns(clock_.now_ns()));  // heaters off on the way out
  started_ = false;
  publish_status();
}

bool Machine::try_submit(uint64_t ticket, const gcode::Command& cmd) {
  if (!queue_.try_push(Queued{ticket, cmd})) return false;
  wake_cv_.notify_one();
  return true;
}

void Machine::inject_stall(int64_t duration_ns) {
  planner_stall_ns_.store(duration_ns, std::memory_order_relaxed);
  servo_stall_ns_.store(duration_ns, std::memory_order_release);
}

namespace {
// Takes a pending stall request and sleeps it out (real time only: a virtual clock's stall is
// the caller's jump of now_ns, run_simulated's HostStall).
void take_stall(std::atomic<int64_t>& request_ns) {
  if (request_ns.load(std::memory_order_relaxed) == 0) return;
  const int64_t ns = request_ns.exchange(0, std::memory_order_acq_rel);
  if (ns > 0) std::this_thread::sleep_for(std::chrono::nanoseconds(ns));
}
}  // namespace

void Machine::emergency_stop(const std::string& reason) {
  estop_.store(true);
  cancel_.store(true);
  interrupt_.store(true);
  set_error("emergency stop: " + reason);
  if (thermal_) thermal_->all_off(seconds_from_ns(clock_.now_ns()));
  wake_cv_.notify_all();
}

void Machine::flush(bool heaters_off) {
  if (heaters_off) {
    flush_heaters_off_.store(true);
    if (thermal_) thermal_->all_off(seconds_from_ns(clock_.now_ns()));
  }
  flush_requested_.store(true);
  interrupt_.store(true);
  wake_cv_.notify_all();
}

// The planner thread's side of flush(): the queue drained (each command completed as dropped),
// the executor's motion stopped, the heaters off again behind the drain.
void Machine::run_flush() {
  flush_running_.store(true);
  flush_requested_.store(false);
  const bool heaters_off = flush_heaters_off_.exchange(false);
  // What is queued now (a command submitted while the drain runs, e.g. a cancel's park move
  // answering the drops' completions, is not dropped).
  size_t n = queue_.size();
  Queued q;
  while (n-- > 0 && queue_.try_pop(q)) {
    flushed_.fetch_add(1, std::memory_order_relaxed);
    if (on_done_)
      on_done_(CommandDone{q.ticket, Error{"dropped: the machine's queue was flushed (cancel)"}});
  }
  if (heaters_off && thermal_) thermal_->all_off(seconds_from_ns(clock_.now_ns()));
  executor_->flush_motion(cancel_);
  flushes_.fetch_add(1, std::memory_order_relaxed);
  // A flush requested meanwhile runs at the next turn; else the interrupt ends with this one.
  if (!cancel_.load() && !flush_requested_.load()) interrupt_.store(false);
  // Published before the flush ends, so whoever sees idle() after it reads the stop's position
  // (status() makes the state live; a sanitizer run read the position from before the travel).
  publish_status();
  flush_running_.store(false);
}

// A thermal fault: every heater is already off (ThermalLoop::trip); the motion stops the way an
// emergency stop stops it (queued commands cancelled, the executor's motion ended) and the message
// names the heater, the rule and its numbers.
void Machine::on_thermal_fault(const std::string& message) {
  estop_.store(true);
  cancel_.store(true);
  interrupt_.store(true);
  set_error(message);
  wake_cv_.notify_all();
}

void Machine::thermal_step() {
  if (!thermal_) return;
  if (auto f = thermal_->step_to(seconds_from_ns(clock_.now_ns()))) on_thermal_fault(*f);
}

void Machine::thermal_main() {
  // The thermal loop's own thread: reports every 0.3 s of machine time need an answer well within
  // the MCU's 3 s; in virtual time it follows the clock as the servo thread advances it.
  while (!stopping_.load()) {
    thermal_step();
    std::this_thread::sleep_for(clock_.is_virtual() ? std::chrono::milliseconds(1)
                                                    : std::chrono::milliseconds(20));
  }
}

void Machine::set_error(const std::string& message) {
  std::lock_guard lock(error_mutex_);
  last_error_ = message;
}

MachineStatus Machine::status() const {
  MachineStatus s = status_.load();
  if (executor_) executor_->motion_status(s);  // live: the planner thread may be blocked
  fill_thermal(s);                             // live: the thermal thread moves on its own
  // The published state is the planner thread's as of its last publish, which a long command
  // (G28, M109) holds off; a command queued or running since is busy now (a status request right
  // after a G28 was sent read "idle" with the G28 homing).
  // An emergency stop is live too: the line after an M112 is refused whether or not the planner
  // thread has published since (a job's next line, in virtual time, read "busy").
  if (estop_.load())
    s.state = MachineState::kEmergencyStopped;
  else if (s.state == MachineState::kIdle && (!queue_.empty() || executing_.load()))
    s.state = MachineState::kBusy;
  // And the other way: the planner thread publishes before it clears its flags (a command's end,
  // a flush's end), so a machine idle now has its position published; its state is idle now too.
  else if (s.state == MachineState::kBusy && !estop_.load() && !stopping_.load() &&
           !(executor_ && executor_->faulted()) && idle())
    s.state = MachineState::kIdle;
  return s;
}

bool Machine::healthy() const {
  if (estop_.load()) return false;
  const int64_t last = servo_last_cycle_ns_.load(std::memory_order_acquire);
  const auto window_ns = static_cast<int64_t>(100.0 * 1e9 / options_.servo_rate_hz);
  return last != 0 && clock_.now_ns() - last < window_ns;
}

bool Machine::idle() const {
  if (!queue_.empty() || executing_.load() || flushing()) return false;
  return executor_->faulted() || (!executor_->motion_pending() && !executor_->settling());
}

void Machine::publish_status() {
  MachineStatus s;
  if (estop_.load()) {
    s.state = MachineState::kEmergencyStopped;
  } else if (stopping_.load()) {
    s.state = MachineState::kStopped;
  } else if (executor_ && executor_->faulted()) {
    s.state = MachineState::kError;  // not busy: the queued motion will not run
  } else {
    s.state = idle() ? MachineState::kIdle : MachineState::kBusy;
  }
  if (executor_) {
    executor_->position(s.pos_mm);
    executor_->homed_axes(s.homed_axes);
    executor_->motion_status(s);
  }
  fill_thermal(s);
  if (thermal_ && !cold_extrusion_allowed_ && thermal_->find_heater('T', 0) >= 0)
    s.min_extrude_temp_c = min_extrude_temp_c_;
  s.queue_depth = static_cast<uint32_t>(queue_.size());
  s.queue_capacity = static_cast<uint32_t>(queue_.capacity());
  s.commands_executed = executed_.load();
  s.commands_rejected = rejected_.load();
  s.commands_flushed = flushed_.load(std::memory_order_relaxed);
  s.flushes = flushes_.load(std::memory_order_relaxed);
  {
    std::lock_guard lock(error_mutex_);
    std::snprintf(s.last_error, sizeof s.last_error, "%s", last_error_.c_str());
  }
  status_.store(s);
}

void Machine::fill_thermal(MachineStatus& s) const {
  if (!thermal_) return;
  thermal_->snapshot(s.heaters, s.num_heaters, s.fans, s.num_fans);
  bool have_t = false, have_b = false;
  for (int i = 0; i < s.num_heaters; ++i) {
    const HeaterStatus& h = s.heaters[i];
    if (h.marlin == 'T' && !have_t) {
      have_t = true;
      s.hotend_c = h.temp_c;
      s.hotend_target_c = h.target_c;
    } else if (h.marlin == 'B' && !have_b) {
      have_b = true;
      s.bed_c = h.temp_c;
      s.bed_target_c = h.target_c;
    }
  }
  std::snprintf(s.temp_report, sizeof s.temp_report, "%s", thermal_->marlin_report().c_str());
}

// Klipper's "Extrude below minimum temp" (extras/heaters.py can_extrude), Marlin's
// PREVENT_COLD_EXTRUSION: the hotend that extrudes (T0) is below min_extrude_temp.
std::string Machine::why_not_extrude() const {
  if (!thermal_ || cold_extrusion_allowed_ || min_extrude_temp_c_ <= 0.0) return {};
  const int hotend = thermal_->find_heater('T', 0);
  if (hotend < 0) return {};
  const double temp_c = thermal_->temp_c(hotend);  // NaN before its first report
  if (temp_c >= min_extrude_temp_c_) return {};
  char at[48];
  if (std::isnan(temp_c))
    std::snprintf(at, sizeof at, "has no temperature reading yet");
  else
    std::snprintf(at, sizeof at, "is at %.1f C", temp_c);
  char buf[240];
  std::snprintf(buf, sizeof buf,
                "Extrude below minimum temp: %s %s, min_extrude_temp is %.0f C (heat it with M109 "
                "S<temp>; M302 P1 allows cold extrusion)",
                thermal_->spec(hotend).name.c_str(), at, min_extrude_temp_c_);
  return buf;
}

bool Machine::is_machine_command(const gcode::Command& cmd) const {
  if (cmd.is('M', 104) || cmd.is('M', 109) || cmd.is('M', 140) || cmd.is('M', 190) ||
      cmd.is('M', 302) || cmd.is('M', 303) || (cmd.is('G', 10) && cmd.has('P')))
    return true;
  // Fans are the machine's when it has any; otherwise the executor takes (and ignores) them.
  return thermal_ && thermal_->num_fans() > 0 && (cmd.is('M', 106) || cmd.is('M', 107));
}

Status Machine::wait_for(const std::function<bool(double now_s)>& done, const char* what,
                         double until_s) {
  executor_->release_lookahead();
  struct MotionWait {  // cleared however the wait ends
    CommandExecutor& e;
    ~MotionWait() { e.set_waiting_for_motion(false); }
  } motion_wait{*executor_};
  for (;;) {
    if (thermal_)
      if (auto f = thermal_->fault()) return Error{*f};
    if (interrupt_.load()) return Error{std::string(what) + " cancelled"};
    const double now_s = seconds_from_ns(clock_.now_ns());
    if (now_s >= until_s || done(now_s)) return Status::Ok();
    const double step_s = std::min(0.02, until_s - now_s);
    if (clock_.is_virtual()) {
      // Virtual time is the wait's own while nothing moves (the servo thread advances it only for
      // motion): 20 ms per step, the heaters following the clock.
      const bool motion = executor_->motion_pending() || executor_->settling();
      executor_->set_waiting_for_motion(motion);
      if (!motion) {
        const int64_t until_ns = clock_.now_ns() + static_cast<int64_t>(std::ceil(step_s * 1e9));
        if (servo_carries_heaters_ && started_) {
          // The heaters' messages ride on the motion MCUs' sessions: the servo thread runs this
          // time, its cycles servicing them (servo_main).
          virtual_wait_until_ns_.store(until_ns, std::memory_order_release);
          while (clock_.now_ns() < until_ns && !interrupt_.load() && !stopping_.load())
            std::this_thread::sleep_for(std::chrono::microseconds(50));
        } else {
          clock_.sleep_until_ns(until_ns);
        }
        thermal_step();
      } else {
        std::this_thread::sleep_for(std::chrono::microseconds(200));
      }
    } else {
      std::this_thread::sleep_for(std::chrono::duration<double>(step_s));
    }
    publish_status();
  }
}

// Heaters, fans and waits are the machine's own (engine/thermal_loop.hpp); the rest goes to the
// executor. Marlin's semantics: M104/M140 set, M109/M190 set and wait (S: for heating only, R: for
// heating or cooling), G10 P<tool> S<active> sets the tool's temperature, M106 P<fan> S<0..255>,
// M107 P<fan>, M303 E<heater, -1 bed> S<temp> C<cycles> U<use>.
Status Machine::execute_machine_command(const gcode::Command& cmd) {
  if (cmd.is('M', 302)) {  // Marlin: S<temp> the minimum, P1 allow cold extrusion, P0 do not
    if (cmd.has('S')) {
      if (!(cmd.get('S') >= 0.0)) return Error{"M302: S must be >= 0 C"};
      min_extrude_temp_c_ = cmd.get('S');
    }
    if (cmd.has('P')) cold_extrusion_allowed_ = cmd.get('P') != 0.0;
    if (!cmd.has('S') && !cmd.has('P')) {  // Marlin's report (gcode/config/M302.cpp)
      char buf[96];
      std::snprintf(buf, sizeof buf, "echo:Cold extrudes are %s (min temp %gC)",
                    cold_extrusion_allowed_ || !thermal_ ? "enabled" : "disabled",
                    min_extrude_temp_c_);
      command_report_ = buf;
    }
    return Status::Ok();
  }
  if (!thermal_) {
    if (cmd.is('M', 303))
      return Error{"M303: this machine has no heaters (no heaters: section in the config)"};
    return Status::Ok();  // no heaters configured: nothing to heat, nothing to wait for
  }
  const double now_s = seconds_from_ns(clock_.now_ns());
  if (cmd.is('M', 106) || cmd.is('M', 107)) {
    const int fan = cmd.has('P') ? static_cast<int>(cmd.get('P')) : 0;
    const double speed = cmd.is('M', 107) ? 0.0 : (cmd.has('S') ? cmd.get('S') / 255.0 : 1.0);
    if (Status st = thermal_->set_fan(fan, speed, now_s); !st) {
      // A fan index beyond the machine's part fans is ignored, as Marlin does
      // (gcode/temp/M106_M107.cpp: `if (pfan < _CNT_P)`): a slicer's auxiliary or chamber fan
      // (OrcaSlicer's `M106 P2 S0`, `M106 P3 S180`) must not end a print job. Said, not refused.
      command_report_ = "echo:" + st.error().message + ": M" + std::to_string(cmd.code) + " P" +
                        std::to_string(fan) + " ignored";
    }
    return Status::Ok();
  }
  if (cmd.is('M', 303)) {
    const int e = cmd.has('E') ? static_cast<int>(cmd.get('E')) : 0;
    const int heater = e < 0 ? thermal_->find_heater('B') : thermal_->find_heater('T', e);
    if (heater < 0) return Error{"M303: no heater E" + std::to_string(e)};
    const double target =
        cmd.has('S') ? cmd.get('S') : (e < 0 ? 70.0 : 150.0);  // Marlin's defaults
    const int cycles = cmd.has('C') ? static_cast<int>(cmd.get('C')) : 5;
    if (Status st = thermal_->start_autotune(heater, target, cycles); !st) return st;
    const bool use = cmd.has('U') && cmd.get('U') != 0;
    std::optional<Result<thermal::PidParams>> result;
    Status st = wait_for([&](double) {
      result = thermal_->autotune_done(use);
      return result.has_value();
    });
    if (!st) return st;
    if (!result->ok()) return result->error();
    // Marlin's M303 report (module/temperature.cpp, PID_autotune), which hosts such as OctoPrint
    // read, then the values under this project's config keys.
    const thermal::PidParams& g = result->value();
    const std::string& name = thermal_->spec(heater).name;
    char buf[512];
    std::snprintf(buf, sizeof buf,
                  "PID Autotune finished! Put the last Kp, Ki and Kd constants from below into "
                  "Configuration.h\n#define DEFAULT_Kp %.2f\n#define DEFAULT_Ki %.2f\n"
                  "#define DEFAULT_Kd %.2f\n// heaters.%s.pid: {kp: %.3f, ki: %.3f, kd: %.3f}%s",
                  g.kp, g.ki, g.kd, name.c_str(), g.kp, g.ki, g.kd,
                  use ? " (in use until a restart; put it into the config to keep it)"
                      : " (not in use: M303 ... U1 uses it)");
    command_report_ = buf;
    return Status::Ok();
  }
  const bool bed = cmd.is('M', 140) || cmd.is('M', 190);
  const char tool_letter = cmd.is('G', 10) ? 'P' : 'T';
  const int tool = !bed && cmd.has(tool_letter) ? static_cast<int>(cmd.get(tool_letter)) : 0;
  const int heater = bed ? thermal_->find_heater('B') : thermal_->find_heater('T', tool);
  if (heater < 0) {
    if (bed) return Status::Ok();  // Marlin without a heated bed ignores M140/M190
    return Error{"no hotend T" + std::to_string(tool) + " in the config"};
  }
  const bool wait = cmd.is('M', 109) || cmd.is('M', 190);
  bool heating_only = true;
  if (cmd.has('S')) {
    if (Status st = thermal_->set_target(heater, cmd.get('S')); !st) return st;
  } else if (cmd.has('R') && !cmd.is('G', 10)) {
    heating_only = false;
    if (Status st = thermal_->set_target(heater, cmd.get('R')); !st) return st;
  }
  publish_status();
  if (!wait) return Status::Ok();
  // An M108 before this wait began is not for it (Marlin sets wait_for_heatup at the wait's start).
  break_heater_wait_.store(false);
  Status st = wait_for([&](double t) {
    return break_heater_wait_.load() || thermal_->reached(heater, heating_only, t);
  });
  if (st && break_heater_wait_.exchange(false)) {
    char buf[120];
    std::snprintf(buf, sizeof buf, "echo:%s wait ended by M108 at %.1f C (target %.0f C kept)",
                  cmd.is('M', 109) ? "M109" : "M190", thermal_->temp_c(heater),
                  thermal_->target_c(heater));
    command_report_ = buf;
  }
  return st;
}

// The planner stage's one entry for a command, whichever thread runs it (the planner thread in
// real and virtual time, the caller in batch mode): the machine's own commands (heaters, fans,
// waits) here, the rest to the executor; the outcome counted.
Status Machine::dispatch(const gcode::Command& cmd) {
  Status st;
  if (estop_.load()) {
    st = Error{"machine is emergency-stopped; restart the daemon (or send M999) to clear"};
  } else if (is_machine_command(cmd)) {
    st = execute_machine_command(cmd);
  } else {
    st = executor_->execute(cmd, interrupt_);
    // A G4 on a machine at rest: Marlin's dwell still waits (an M400 after it too).
    if (const double dwell_s = executor_->take_idle_dwell_s(); st && dwell_s > 0.0) {
      const double end_s = seconds_from_ns(clock_.now_ns()) + dwell_s;
      st = wait_for([](double) { return false; }, "G4 dwell", end_s);
    }
  }
  if (st) {
    executed_.fetch_add(1, std::memory_order_relaxed);
  } else if (flush_requested_.load() && !estop_.load()) {
    flushed_.fetch_add(1, std::memory_order_relaxed);  // cut short by a flush: not a refusal
  } else {
    rejected_.fetch_add(1, std::memory_order_relaxed);
    // Once stopped, the commands refused after it do not hide why it stopped.
    if (!estop_.load()) set_error(st.error().to_string());
  }
  return st;
}

Status Machine::execute_inline(const gcode::Command& cmd) {
  if (started_) return Error{"execute_inline: the machine's threads are running"};
  return dispatch(cmd);
}

void Machine::planner_main() {
  while (!stopping_.load()) {
    take_stall(planner_stall_ns_);
    if (flush_requested_.load() && !estop_.load()) {
      run_flush();
      continue;
    }
    Queued q;
    // Busy from before the command leaves the queue: the servo thread reads the queue, then this
    // flag (servo_main), so it never sees neither while a command is on its way to the executor.
    // (Popped first, a command was briefly in neither, and virtual time could run on past a
    // waypoint the planner was about to release: a DC-servo run differed by 0.2 ms of path time.)
    executing_.store(true);
    if (!queue_.try_pop(q)) {
      executing_.store(false);
      {
        std::unique_lock lock(wake_mutex_);
        wake_cv_.wait_for(lock, std::chrono::milliseconds(5));
      }
      if (estop_.load()) cancel_.store(true);  // stays latched
      // Virtual time with a source's commands on their way: no idle release (set_input_coming).
      if (!(clock_.is_virtual() && input_coming_.load(std::memory_order_acquire)))
        executor_->idle_tick(interrupt_);
      publish_status();
      continue;
    }
    const Status st = dispatch(q.cmd);
    publish_status();  // before the flag: idle() true means the command's position is published
    executing_.store(false);
    if (on_done_) on_done_(CommandDone{q.ticket, st, std::exchange(command_report_, {})});
  }
}

// One servo period, whoever calls it (servo_main on the clock, servo_cycle_inline in one-thread
// runs): the lateness counted, a lost period reported, the executor's cycle, the status published.
void Machine::servo_tick(ServoStatus& st, int64_t wake_ns, int64_t late_ns, int64_t period_ns) {
  st.latency.add(late_ns);
  ++st.cycles;
  if (late_ns > period_ns) {
    st.deadline_misses += static_cast<uint64_t>(late_ns / period_ns);
    executor_->on_deadline_miss(wake_ns, late_ns);  // e.g. into the flight recorder
  }
  executor_->servo_cycle(wake_ns, cancel_.load(std::memory_order_relaxed));
  st.last_wake_ns = wake_ns;
  servo_status_.store(st);
  servo_last_cycle_ns_.store(wake_ns, std::memory_order_release);
}

Status Machine::servo_cycle_inline(int64_t now_ns) {
  if (started_) return Error{"servo_cycle_inline: the machine's threads are running"};
  const auto period_ns = static_cast<int64_t>(1e9 / options_.servo_rate_hz);
  const int64_t due_ns =
      inline_servo_.last_wake_ns == 0 ? now_ns : inline_servo_.last_wake_ns + period_ns;
  servo_tick(inline_servo_, now_ns, now_ns - due_ns, period_ns);
  return Status::Ok();
}

void Machine::idle_tick_inline() {
  if (started_) return;
  executor_->idle_tick(interrupt_);
}

void Machine::servo_main() {
  const auto period_ns = static_cast<int64_t>(1e9 / options_.servo_rate_hz);
  ServoStatus st;
  int64_t deadline = clock_.now_ns() + period_ns;
  while (!stopping_.load(std::memory_order_relaxed)) {
    if (clock_.is_virtual() &&
        ((!executor_->motion_pending() && !executor_->settling()) ||
         !executor_->may_advance_virtual(!queue_.empty() || executing_.load()))) {
      // Virtual time moves only while there is motion to simulate; otherwise wait for work. A
      // heater wait may advance the clock meanwhile (Machine::wait_for): the next cycle is due one
      // period after the present, not at a deadline the idle time left behind (no false misses).
      // When the heaters' messages ride on the motion MCUs' sessions, the wait's time is this
      // thread's to run instead, period by period (each cycle services the sessions).
      if (const int64_t now = clock_.now_ns();
          now < virtual_wait_until_ns_.load(std::memory_order_acquire)) {
        clock_.sleep_until_ns(now + period_ns);
        servo_tick(st, clock_.now_ns(), 0, period_ns);
        servo_last_cycle_ns_.store(clock_.now_ns(), std::memory_order_release);
        deadline = clock_.now_ns() + period_ns;
        continue;
      }
      std::this_thread::sleep_for(std::chrono::microseconds(200));
      servo_last_cycle_ns_.store(clock_.now_ns(), std::memory_order_release);
      deadline = clock_.now_ns() + period_ns;
      continue;
    }
    take_stall(servo_stall_ns_);  // before the sleep: the stall makes this cycle late
    clock_.sleep_until_ns(deadline);
    const int64_t wake = clock_.now_ns();
    const int64_t late_ns = wake - deadline;
    if (late_ns > period_ns)  // a whole period lost: counted (servo_tick), no catching up
      deadline += (late_ns / period_ns) * period_ns;
    servo_tick(st, wake, late_ns, period_ns);
    deadline += period_ns;
  }
  if (executor_) executor_->servo_stopped();
}

}  // namespace feedloop::engine
