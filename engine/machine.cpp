#include "engine/machine.hpp"

#include <system_error>

#include <algorithm>  // std::min
#include <chrono>     // wait_for
#include <cstdio>     // snprintf
#include <thread>

#include "engine/realtime.hpp"

namespace feedloop::engine {

const char* to_string(MachineState s) {
  switch (s) {
    case MachineState::kIdle: return "idle";
    case MachineState::kBusy: return "busy";
    case MachineState::kError: return "error";
    case MachineState::kEmergencyStopped: return "emergency_stopped";
    case MachineState::kStopped: return "stopped";
  }
  return "unknown";
}

Machine::Machine(MachineOptions options, Clock& clock, std::unique_ptr<CommandExecutor> executor)
    : options_(options),
      clock_(clock),
      executor_(std::move(executor)),
      queue_(options.command_queue_capacity) {
  hotend_.max_slew_c_s = options_.heater_slew_c_s;
  bed_.max_slew_c_s = options_.heater_slew_c_s / 4.0;
  publish_status();
}

Machine::~Machine() { stop(); }

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
  stopping_.store(true);
  wake_cv_.notify_all();
  if (planner_thread_.joinable()) planner_thread_.join();
  if (servo_thread_.joinable()) servo_thread_.join();
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
  set_error("emergency stop: " + reason);
  wake_cv_.notify_all();
}

void Machine::set_error(const std::string& message) {
  std::lock_guard lock(error_mutex_);
  last_error_ = message;
}

MachineStatus Machine::status() const {
  MachineStatus s = status_.load();
  if (executor_) executor_->motion_status(s);  // live: the planner thread may be blocked
  return s;
}

bool Machine::healthy() const {
  if (estop_.load()) return false;
  const int64_t last = servo_last_cycle_ns_.load(std::memory_order_acquire);
  const auto window_ns = static_cast<int64_t>(100.0 * 1e9 / options_.servo_rate_hz);
  return last != 0 && clock_.now_ns() - last < window_ns;
}

bool Machine::idle() const {
  if (!queue_.empty() || executing_.load()) return false;
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
  s.hotend_c = hotend_.temp_c;
  s.hotend_target_c = hotend_.target_c;
  s.bed_c = bed_.temp_c;
  s.bed_target_c = bed_.target_c;
  s.queue_depth = static_cast<uint32_t>(queue_.size());
  s.queue_capacity = static_cast<uint32_t>(queue_.capacity());
  s.commands_executed = executed_.load();
  s.commands_rejected = rejected_.load();
  {
    std::lock_guard lock(error_mutex_);
    std::snprintf(s.last_error, sizeof s.last_error, "%s", last_error_.c_str());
  }
  status_.store(s);
}

// Heater commands and waits are the machine's own; everything else goes to the executor.
Status Machine::execute_machine_command(const gcode::Command& cmd) {
  // G10 P<tool> S<active> R<standby>: the temperature form (the active temperature is the target).
  const bool hotend = cmd.is('M', 104) || cmd.is('M', 109) || cmd.is('G', 10);
  HeaterSim& h = hotend ? hotend_ : bed_;
  const bool wait = cmd.is('M', 109) || cmd.is('M', 190);
  if (cmd.has('S')) h.target_c = cmd.get('S');
  else if (cmd.has('R') && !cmd.is('G', 10)) h.target_c = cmd.get('R');
  if (!wait) return Status::Ok();
  if (clock_.is_virtual()) {  // no one advances time for a wait in virtual time: settle at once
    h.temp_c = h.target_c > 0 ? h.target_c : h.ambient_c;
    return Status::Ok();
  }
  int64_t last_ns = clock_.now_ns();
  while (!h.at_target()) {
    if (cancel_.load()) return Error{"wait for temperature cancelled"};
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    const int64_t now = clock_.now_ns();
    hotend_.advance(seconds_from_ns(now - last_ns));
    bed_.advance(seconds_from_ns(now - last_ns));
    last_ns = now;
    publish_status();
  }
  return Status::Ok();
}

// The planner stage's one entry for a command, whichever thread runs it (the planner thread in
// real and virtual time, the caller in batch mode): the machine's own commands (heaters, waits)
// here, the rest to the executor; the outcome counted.
Status Machine::dispatch(const gcode::Command& cmd) {
  Status st;
  if (estop_.load()) {
    st = Error{"machine is emergency-stopped; restart the daemon (or send M999) to clear"};
  } else if (cmd.is('M', 104) || cmd.is('M', 109) || cmd.is('M', 140) || cmd.is('M', 190) ||
             (cmd.is('G', 10) && cmd.has('P'))) {
    st = execute_machine_command(cmd);
  } else {
    st = executor_->execute(cmd, cancel_);
  }
  if (st) {
    executed_.fetch_add(1, std::memory_order_relaxed);
  } else {
    rejected_.fetch_add(1, std::memory_order_relaxed);
    set_error(st.error().to_string());
  }
  return st;
}

Status Machine::execute_inline(const gcode::Command& cmd) {
  if (started_) return Error{"execute_inline: the machine's threads are running"};
  return dispatch(cmd);
}

void Machine::planner_main() {
  int64_t last_heater_ns = clock_.now_ns();
  while (!stopping_.load()) {
    take_stall(planner_stall_ns_);
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
      const int64_t now = clock_.now_ns();
      hotend_.advance(seconds_from_ns(now - last_heater_ns));
      bed_.advance(seconds_from_ns(now - last_heater_ns));
      last_heater_ns = now;
      if (estop_.load()) cancel_.store(true);  // stays latched
      executor_->idle_tick(cancel_);
      publish_status();
      continue;
    }
    const Status st = dispatch(q.cmd);
    executing_.store(false);
    publish_status();
    if (on_done_) on_done_(CommandDone{q.ticket, st});
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
  executor_->idle_tick(cancel_);
}

void Machine::servo_main() {
  const auto period_ns = static_cast<int64_t>(1e9 / options_.servo_rate_hz);
  ServoStatus st;
  int64_t deadline = clock_.now_ns() + period_ns;
  while (!stopping_.load(std::memory_order_relaxed)) {
    if (clock_.is_virtual() &&
        ((!executor_->motion_pending() && !executor_->settling()) ||
         !executor_->may_advance_virtual(!queue_.empty() || executing_.load()))) {
      // Virtual time moves only while there is motion to simulate; otherwise wait for work.
      std::this_thread::sleep_for(std::chrono::microseconds(200));
      servo_last_cycle_ns_.store(clock_.now_ns(), std::memory_order_release);
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
}

}  // namespace feedloop::engine
