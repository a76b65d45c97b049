#include "engine/machine.hpp"

#include <system_error>

#include <algorithm>  // std::min
#include <chrono>     // wait_for
#include <cstdio>     // snprintf

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

void Machine::planner_main() {
  int64_t last_heater_ns = clock_.now_ns();
  while (!stopping_.load()) {
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
    Status st;
    if (estop_.load()) {
      st = Error{"machine is emergency-stopped; restart the daemon (or send M999) to clear"};
    } else if (q.cmd.is('M', 104) || q.cmd.is('M', 109) || q.cmd.is('M', 140) ||
               q.cmd.is('M', 190) || (q.cmd.is('G', 10) && q.cmd.has('P'))) {
      st = execute_machine_command(q.cmd);
    } else {
      st = executor_->execute(q.cmd, cancel_);
    }
    if (st) {
      executed_.fetch_add(1);
    } else {
      rejected_.fetch_add(1);
      set_error(st.error().to_string());
    }
    executing_.store(false);
    publish_status();
    if (on_done_) on_done_(CommandDone{q.ticket, st});
  }
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
    clock_.sleep_until_ns(deadline);
    const int64_t wake = clock_.now_ns();
    const int64_t late_ns = wake - deadline;
    st.latency.add(late_ns);
    ++st.cycles;
    if (late_ns > period_ns) {  // a whole period lost: count it and do not try to catch up
      st.deadline_misses += static_cast<uint64_t>(late_ns / period_ns);
      deadline += (late_ns / period_ns) * period_ns;
      executor_->on_deadline_miss(wake, late_ns);  // e.g. into the flight recorder
    }
    executor_->servo_cycle(wake, cancel_.load(std::memory_order_relaxed));
    st.last_wake_ns = wake;
    servo_status_.store(st);
    servo_last_cycle_ns_.store(wake, std::memory_order_release);
    deadline += period_ns;
  }
}

}  // namespace feedloop::engine
