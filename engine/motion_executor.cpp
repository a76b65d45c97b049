#include "engine/motion_executor.hpp"

#include <algorithm>  // std::max
#include <cmath>      // std::floor, NAN
#include <cstdio>     // snprintf
#include <thread>     // sleep_for

namespace feedloop::engine {

MotionExecutor::MotionExecutor(const planner::PlannerConfig& pcfg, const StepPipelineParams& sp,
                               std::shared_ptr<stepgen::BatchSink> batches, MotionOptions options)
    : pcfg_(pcfg),
      options_(options),
      kin_(planner::make_kinematics(pcfg_)),
      planner_(pcfg_, *this),
      emitter_(*kin_, pcfg_.servo_period_s),
      queue_(options.move_queue_capacity),
      batches_(std::move(batches)),
      steps_(sp, batches_.get()) {
  interp_ = std::make_unique<planner::Interpreter>(pcfg_, *kin_, planner_);
  timeline_ = std::make_unique<planner::MoveTimeline>(options_.timeline_capacity);
  no_extruder_.next = &steps_;
  pa_advance_s_.store(interp_->state().pressure_advance_s);
  pa_smooth_time_s_.store(interp_->state().pressure_advance_smooth_time_s);
  for (auto& h : homed_axis_mm_) h.store(NAN);
}

// A motion starts from rest: the advance is on for it when its first move has K > 0 (and the
// extruder makes steps); the window is that move's smooth time.
void MotionExecutor::pa_restart(const planner::PlannedMove& first) {
  pa_active_ = first.pressure_advance_s > 0.0 && steps_.params().steps_per_mm[3] > 0.0;
  if (pa_active_) pa_.restart(first.start_mm[3], first.pressure_advance_smooth_time_s);
}

void MotionExecutor::set_control(std::unique_ptr<ServoControl> control) {
  control_ = std::move(control);
  // Samples between the feedback instant (now) and the newest command (control_lead_s ahead).
  const double period_s = pcfg_.servo_period_s;
  // Beyond the lead, 64 samples more: e_t reads the plan at each encoder sample of a report, the
  // oldest of which (the device loop's 10 per report, the transport) lie that far back.
  history_.assign(
      static_cast<size_t>(
          std::max(options_.control_lead_s, options_.lead_s + kDeviceHorizonSlack_s) / period_s) +
          64,
      Sample{});
  stop_tau_.assign(static_cast<size_t>(control_ ? control_->preview_samples() : 0) + 4, 0.0);
}

Status MotionExecutor::execute(const gcode::Command& cmd, const std::atomic<bool>& cancel) {
  cancel_ = &cancel;
  wait_until_s_ = -1.0;
  last_command_ = std::chrono::steady_clock::now();
  const bool motion = cmd.letter == 'G' && cmd.code >= 0 && cmd.code <= 3;
  if (motion && backend_ != nullptr && backend_->fault()) {  // rejected: nothing changes
    char msg[192];
    backend_->fault_message(msg, sizeof msg);
    return Error{std::string("motion stopped: ") + msg};
  }
  if (motion && control_fault_.load()) return Error{std::string("motion stopped: ") + control_fault_text_};
  if (cmd.is('G', 28) && homes_through_endstops()) return home(cmd, cancel);
  if (motion) wait_for_room(cancel);
  if (motion && cancel.load()) return Error{"cancelled before it was planned", cmd.where};
  Status st = interp_->execute(cmd);
  if (st && (cmd.is('M', 18) || cmd.is('M', 84))) motors_off(cmd, cancel);
  if (cmd.is('M', 486)) {
    std::lock_guard<std::mutex> lock(objects_mu_);
    objects_ = interp_->objects();
  }
  planner_queued_.store(planner_.queued());
  const planner::MachineState& ist = interp_->state();
  pa_advance_s_.store(ist.pressure_advance_s, std::memory_order_relaxed);
  pa_smooth_time_s_.store(ist.pressure_advance_smooth_time_s, std::memory_order_relaxed);
  speed_factor_.store(ist.speed_factor, std::memory_order_relaxed);
  flow_factor_.store(ist.flow_factor, std::memory_order_relaxed);
  feedrate_mm_s_.store(ist.feedrate_mm_s, std::memory_order_relaxed);
  relative_xyz_.store(ist.relative_xyz, std::memory_order_relaxed);
  relative_e_.store(ist.e_relative(), std::memory_order_relaxed);
  inches_.store(ist.unit_mm != 1.0, std::memory_order_relaxed);
  if (st && wait_until_s_ >= 0.0) wait_print_time(wait_until_s_, cancel);  // M400
  return st;
}

void MotionExecutor::position(double out_mm[4]) const {
  const planner::Vec4& p = interp_->state().logical_mm;
  for (int i = 0; i < 4; ++i) out_mm[i] = p[static_cast<size_t>(i)];
}

void MotionExecutor::idle_tick(const std::atomic<bool>& cancel) {
  cancel_ = &cancel;
  if (planner_.queued() == 0) return;
  // Release the lookahead's tail when the input pauses, or before the machine runs dry (the
  // held moves contain the deceleration the released ones rely on).
  const auto quiet = std::chrono::steady_clock::now() - last_command_;
  // (The pressure advance takes moves up to a smooth time earlier.)
  const double pa_s = interp_->state().pressure_advance_s > 0.0
                          ? interp_->state().pressure_advance_smooth_time_s
                          : 0.0;
  const bool running_dry =
      telemetry_.anchored.load() &&
      planned_end_s_.load() - executing_print_time_s() < 2.0 * options_.lead_s + pa_s;
  if (running_dry || quiet > std::chrono::duration<double>(options_.input_pause_flush_s)) planner_.flush();
  planner_queued_.store(planner_.queued());
}

void MotionExecutor::release_lookahead() {
  if (planner_.queued() == 0) return;
  planner_.flush();
  planner_queued_.store(planner_.queued());
}

bool MotionExecutor::faulted() const {
  return control_fault_.load() || (backend_ != nullptr && backend_->fault());
}

bool MotionExecutor::motion_pending() const {
  const int h = homing_req_.load();
  const int sr = stop_req_.load();  // a flush's stop: the servo thread has work until it is done
  return planner_queued_.load() > 0 || pushed_.load() != popped_.load() ||
         telemetry_.anchored.load() || h == kHomingRequested || h == kHomingRunning ||
         sr == kStopRequested || sr == kStopRunning ||
         motors_off_req_.load() != 0;  // M84: work for the servo thread too
}

void MotionExecutor::pause_for_machine() {
  if (inline_driver_)
    inline_driver_();
  else
    std::this_thread::sleep_for(std::chrono::microseconds(500));
}

// Every X/Y/Z joint has an endstop on its MCU (axes.<name>.homing): G28 homes through them.
// Otherwise G28 stays the interpreter's move to the home position (batch mode, ideal plants).
bool MotionExecutor::homes_through_endstops() const {
  if (backend_ == nullptr) return false;
  for (int j = 0; j < 3; ++j)
    if (!backend_->can_home(j)) return false;
  return true;
}

// M18/M84 (Marlin's finish_and_disable): the motion planned so far ends (the device loops' hold
// too), then the servo thread switches the drivers off (McuBridge::set_motors_enabled: per MCU).
// Axis letters select joints: a delta's towers and a CoreXY's A and B go together, E alone is the
// extruder's; none: all. M84 S<seconds> alone only sets the idle timeout. The next motion or
// homing switches them on again first (servo_cycle). With allow_moves_before_homing the position
// is kept (the interpreter's old behaviour), so the drivers stay on.
void MotionExecutor::motors_off(const gcode::Command& cmd, const std::atomic<bool>& cancel) {
  const bool letters = cmd.has('X') || cmd.has('Y') || cmd.has('Z') || cmd.has('E');
  if (cmd.has('S') && !letters) return;
  if (pcfg_.allow_moves_before_homing || backend_ == nullptr) return;
  unsigned mask = 0;
  if (!letters) {
    mask = 0xFu;
  } else {
    const bool delta = pcfg_.kinematics == planner::KinematicsKind::delta;
    const bool corexy = pcfg_.kinematics == planner::KinematicsKind::corexy;
    for (int i = 0; i < 3; ++i)
      if (cmd.has(static_cast<char>('X' + i)))
        mask |= delta ? 0x7u : (corexy && i < 2 ? 0x3u : 1u << i);
    if (cmd.has('E')) mask |= 1u << 3;
  }
  planner_.flush();
  planner_queued_.store(planner_.queued());
  {
    struct Waiting {
      std::atomic<bool>& w;
      explicit Waiting(std::atomic<bool>& f) : w(f) { w = true; }
      ~Waiting() { w = false; }
    } waiting(waiting_);
    while (!cancel.load() && motion_pending()) pause_for_machine();
    if (cancel.load()) return;
    motors_off_req_.fetch_or(mask, std::memory_order_release);
    while (!cancel.load() && motors_off_req_.load(std::memory_order_acquire) != 0)
      pause_for_machine();
  }
}

// G28 [X] [Y] [Z] through the endstops. Marlin and Klipper home the named axes (all without
// letters); here the named joints home together, each on its own MCU (Marlin's QUICK_HOME does
// X and Y together too). The homed position is the motor's where it stopped (Klipper's halt
// position: position_endstop + the steps after the trigger), which the interpreter continues from.
Status MotionExecutor::home(const gcode::Command& cmd, const std::atomic<bool>& cancel) {
  for (char p = 'A'; p <= 'Z'; ++p)
    if (cmd.has(p) && !std::isfinite(cmd.get(p)))
      return Error{"G28: parameter is not a finite number", cmd.where};
  // A delta homes its three towers together whatever the letters (Klipper's delta.py: G28 homes
  // all); each carriage stops on its own switch.
  const bool delta = pcfg_.kinematics == planner::KinematicsKind::delta;
  const bool any = !delta && (cmd.has('X') || cmd.has('Y') || cmd.has('Z'));
  bool axes[3];
  unsigned mask = 0;
  for (int i = 0; i < 3; ++i) {
    axes[i] = !any || cmd.has(static_cast<char>('X' + i));
    if (axes[i]) mask |= 1u << i;
  }
  struct Waiting {
    std::atomic<bool>& w;
    explicit Waiting(std::atomic<bool>& f) : w(f) { w = true; }
    ~Waiting() { w = false; }
  } waiting(waiting_);
  // The motion before the G28 ends first (the lookahead's tail released).
  planner_.flush();
  planner_queued_.store(planner_.queued());
  while (motion_pending()) {
    if (cancel.load()) return Error{"G28: cancelled before homing", cmd.where};
    pause_for_machine();
  }
  homing_mask_.store(mask);
  homing_abort_.store(false, std::memory_order_relaxed);
  homing_req_.store(kHomingRequested, std::memory_order_release);
  auto cancelled_at = std::chrono::steady_clock::now();
  bool seen_cancel = false;
  for (;;) {
    const int h = homing_req_.load(std::memory_order_acquire);
    if (h == kHomingDone || h == kHomingFailed) break;
    if (cancel.load() && !seen_cancel) {
      seen_cancel = true;
      cancelled_at = std::chrono::steady_clock::now();
      homing_abort_.store(true, std::memory_order_release);  // a flush too, not only a stop
    }
    // The servo thread aborts a running homing on cancel and reports it failed. When it has ended
    // (the machine stopping: it may leave on the same cycle as the cancel arrives) no answer will
    // come; a second without one is taken the same way.
    if (seen_cancel && !inline_driver_ &&
        (servo_stopped_.load(std::memory_order_acquire) ||
         std::chrono::steady_clock::now() - cancelled_at > std::chrono::seconds(1))) {
      homing_req_.store(kNoHoming);
      interp_->set_unhomed(axes);
      return Error{"G28: cancelled during homing", cmd.where};
    }
    pause_for_machine();
  }
  if (homing_req_.load(std::memory_order_acquire) == kHomingFailed) {
    const std::string why = seen_cancel
                                ? std::string("cancelled during homing (") + homing_error_ + ")"
                                : std::string(homing_error_);
    homing_req_.store(kNoHoming);
    interp_->set_unhomed(axes);
    return Error{"G28: " + why + "; the axes are not homed", cmd.where};
  }
  planner::Vec4 at = interp_->state().machine_mm;
  if (delta) {
    // The carriages' homed heights (each tower's position_endstop: Klipper's per-tower endstop
    // offsets) through the forward kinematics: where the nozzle is.
    const planner::Joints q{homed_joint_mm_[0], homed_joint_mm_[1], homed_joint_mm_[2]};
    Result<planner::Vec3> nozzle = kin_->forward(q);
    if (!nozzle.ok()) {
      homing_req_.store(kNoHoming);
      interp_->set_unhomed(axes);
      return Error{"G28: the homed carriages have no nozzle position: " + nozzle.error().message,
                   cmd.where};
    }
    for (int i = 0; i < 3; ++i) at[static_cast<size_t>(i)] = nozzle.value()[static_cast<size_t>(i)];
  } else {
    // Cartesian: the joints are the axes. CoreXY: the bridge homes the Cartesian carriage (X and Y
    // each with both motors) and says how far that moved an axis it did not home.
    for (int i = 0; i < 3; ++i)
      at[static_cast<size_t>(i)] = axes[i] ? homed_joint_mm_[static_cast<size_t>(i)]
                                           : at[static_cast<size_t>(i)] + homing_shift_mm_[static_cast<size_t>(i)];
  }
  for (int i = 0; i < 3; ++i)
    if (axes[i]) homed_axis_mm_[static_cast<size_t>(i)].store(at[static_cast<size_t>(i)]);
  interp_->set_homed(axes, at);
  homings_.fetch_add(1);
  homing_req_.store(kNoHoming);
  return {};
}

// Servo thread, after a homing: the step generators restart at the homed positions (resync at the
// next move's start), each homed joint's step stream after the homing's last step on its MCU.
void MotionExecutor::after_homing() {
  resync_ = true;
  for (int j = 0; j < kJoints; ++j)
    if (const int64_t c = backend_->homing_last_step_clock(j); c != INT64_MIN)
      steps_.restart_stream(j, c);
}

// Servo thread, while a homing is requested or runs (no motion is anchored: the planner waited).
void MotionExecutor::homing_cycle(double now_s, bool cancel) {
  const int h = homing_req_.load(std::memory_order_acquire);
  if (h == kHomingRequested) {
    if (cancel) {
      std::snprintf(homing_error_, sizeof homing_error_, "cancelled");
      homing_req_.store(kHomingFailed, std::memory_order_release);
      return;
    }
    if (telemetry_.anchored.load(std::memory_order_relaxed) || !queue_.empty()) return;
    if (!backend_->start_homing(homing_mask_.load(), now_s, homing_error_, sizeof homing_error_)) {
      homing_req_.store(kHomingFailed, std::memory_order_release);
      return;
    }
    homing_req_.store(kHomingRunning, std::memory_order_release);
    return;
  }
  if (cancel) backend_->abort_homing("cancelled");
  switch (backend_->homing_state()) {
    case ServoBackend::HomingState::kRunning:
      return;
    case ServoBackend::HomingState::kDone:
      for (int j = 0; j < kJoints; ++j)
        homed_joint_mm_[static_cast<size_t>(j)] = backend_->homed_position_mm(j);
      for (int i = 0; i < 3; ++i) homing_shift_mm_[static_cast<size_t>(i)] = backend_->homing_shift_mm(i);
      after_homing();
      homing_req_.store(kHomingDone, std::memory_order_release);
      return;
    default:
      backend_->homing_error(homing_error_, sizeof homing_error_);
      after_homing();
      homing_req_.store(kHomingFailed, std::memory_order_release);
      return;
  }
}

void MotionExecutor::motion_status(MachineStatus& s) const {
  s.moving = telemetry_.anchored.load(std::memory_order_relaxed);
  s.print_time_s = telemetry_.print_time_s.load(std::memory_order_relaxed);
  s.planned_until_s = planned_end_s_.load(std::memory_order_relaxed);
  s.pressure_advance_s = pa_advance_s_.load(std::memory_order_relaxed);
  s.pressure_advance_smooth_time_s = pa_smooth_time_s_.load(std::memory_order_relaxed);
  s.speed_factor = speed_factor_.load(std::memory_order_relaxed);
  s.flow_factor = flow_factor_.load(std::memory_order_relaxed);
  s.feedrate_mm_s = feedrate_mm_s_.load(std::memory_order_relaxed);
  s.absolute_coordinates = !relative_xyz_.load(std::memory_order_relaxed);
  s.absolute_extrude = !relative_e_.load(std::memory_order_relaxed);
  s.inches = inches_.load(std::memory_order_relaxed);
  s.moves_planned = moves_emitted_.load(std::memory_order_relaxed);
  s.segments_queued = pushed_.load() - popped_.load();
  s.motion_starts = telemetry_.anchors.load(std::memory_order_relaxed);
  s.lost_step_events = lost_step_events_.load(std::memory_order_relaxed) +
                       (backend_ != nullptr ? backend_->device_lost_step_events() : 0);
  s.late_cycles = late_cycles_.load(std::memory_order_relaxed);
  s.tracking_error_samples = e_t_samples_.load(std::memory_order_relaxed);
  s.tracking_error_mean_mm =
      s.tracking_error_samples > 0 ? e_t_sum_mm_.load(std::memory_order_relaxed) / static_cast<double>(s.tracking_error_samples) : 0.0;
  s.tracking_error_max_mm = e_t_max_mm_.load(std::memory_order_relaxed);
  for (size_t j = 0; j < 4; ++j) s.step_count[j] = step_count_[j].load(std::memory_order_relaxed);
  s.has_step_count = true;
  if (backend_ != nullptr) {  // the MCUs: encoder positions, and a fault naming the MCU
    for (int j = 0; j < 4; ++j) s.encoder_mm[j] = backend_->encoder_mm(j);
    s.encoder_samples = backend_->encoder_samples();
    backend_->links(s.links);
    backend_->device_loops(s.device_loops);
    if (backend_->fault()) backend_->fault_message(s.last_error, sizeof s.last_error);
    for (int j = 0; j < 3; ++j) {
      s.endstop[j] = static_cast<int8_t>(backend_->endstop_state(j));
      s.endstop_at_max[j] = backend_->endstop_at_max(j);
    }
  }
  for (size_t i = 0; i < 3; ++i)
    s.homed_position_mm[i] = homed_axis_mm_[i].load(std::memory_order_relaxed);
  s.homings = homings_.load(std::memory_order_relaxed);
  s.homing = homing_req_.load(std::memory_order_relaxed) != kNoHoming;
  if (control_fault_.load()) std::snprintf(s.last_error, sizeof s.last_error, "%s", control_fault_text_);
}

void MotionExecutor::on_move(const planner::PlannedMove& m) {
  if (tap_ != nullptr) tap_->on_planned_move(m);
  queue_move(m);
}

void MotionExecutor::queue_move(const planner::PlannedMove& m) {
  if (pushed_.load() == popped_.load() && !telemetry_.anchored.load())
    idle_base_s_.store(m.start_time_s);  // the servo side is at rest: motion restarts here
  while (!queue_.try_push(m)) {
    if (cancel_ != nullptr && cancel_->load()) return;
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  pushed_.fetch_add(1, std::memory_order_release);
  moves_emitted_.fetch_add(1, std::memory_order_relaxed);
  if (m.end_time_s() > planned_end_s_.load(std::memory_order_relaxed))
    planned_end_s_.store(m.end_time_s(), std::memory_order_relaxed);
}

void MotionExecutor::on_event(const planner::PlannerEvent& e) {
  if (e.kind == planner::EventKind::moves_done) wait_until_s_ = e.time_s;
  // G4 (Marlin's dwell waits, also with nothing moving; an M400 after it waits for its end).
  // Right after motion (still running, holding or settling) the dwell becomes motion: the machine
  // stands at the plan's end for it, in the timeline, so the loops keep holding and virtual time
  // simulates it. The planner flushed its moves before the event: its position is that end.
  // At rest (or homing: the plan's end is not where the carriages are) the machine waits the time
  // on its clock instead (Machine::dispatch, take_idle_dwell_s).
  if (e.kind == planner::EventKind::dwell && e.duration_s > 0.0) {
    const int h = homing_req_.load();
    const bool homing = h == kHomingRequested || h == kHomingRunning;
    if (!homing && (motion_pending() || settling()))
      queue_move(planner::standstill_move(planner_.position(), e.time_s, e.duration_s, e.line));
    else
      idle_dwell_s_ += e.duration_s;
  }
}

double MotionExecutor::executing_print_time_s() const {
  return telemetry_.anchored.load(std::memory_order_relaxed)
             ? telemetry_.print_time_s.load(std::memory_order_relaxed)
             : idle_base_s_.load(std::memory_order_relaxed);
}

// A servo cycle that woke late: an event for the telemetry tap (the recorder logs it).
void MotionExecutor::on_deadline_miss(int64_t /*now_ns*/, int64_t late_ns) {
  if (tap_ == nullptr) return;
  ServoEvent e;
  e.kind = ServoEventKind::kDeadlineMiss;
  e.print_time_s = telemetry_.print_time_s.load(std::memory_order_relaxed);
  e.size_mm = static_cast<double>(late_ns) * 1e-9;  // lateness, s
  tap_->on_servo_event(e);
}

// Virtual time may run on while enough planned motion lies ahead, or when the planner holds
// nothing back; never into moves the lookahead has not released yet.
bool MotionExecutor::may_advance_virtual(bool planner_busy) const {
  if (waiting_.load()) return true;  // M400 flushed everything and waits for the machine
  // Planned motion ahead counts only when the servo side has some (anchored, or moves queued to
  // it). At rest, planned_end_s_ and idle_base_s_ are the last motion's end and start, and their
  // difference is no lead: with it, virtual time ran on for 1-3 ms while the lookahead held a new
  // job's first moves, as far as the host's pace let it (a check pattern's e_t then varied).
  const bool has_motion = telemetry_.anchored.load() || pushed_.load() != popped_.load();
  if (has_motion && planned_end_s_.load() - executing_print_time_s() > options_.lead_s + 0.01)
    return true;
  return !planner_busy && planner_queued_.load() == 0;
}

void MotionExecutor::wait_for_room(const std::atomic<bool>& cancel) {
  struct Waiting {
    std::atomic<bool>& w;
    explicit Waiting(std::atomic<bool>& f) : w(f) { w = true; }
    ~Waiting() { w = false; }
  } waiting(waiting_);
  while (!cancel.load()) {
    if (pushed_.load() == popped_.load() && !telemetry_.anchored.load()) return;
    if (planned_end_s_.load(std::memory_order_relaxed) - executing_print_time_s() <=
        options_.max_buffered_s)
      return;
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
}

void MotionExecutor::wait_print_time(double t_s, const std::atomic<bool>& cancel) {
  planner_.flush();
  struct Waiting {
    std::atomic<bool>& w;
    explicit Waiting(std::atomic<bool>& f) : w(f) { w = true; }
    ~Waiting() { w = false; }
  } waiting(waiting_);
  planner_queued_.store(planner_.queued());
  while (!cancel.load()) {
    if (!motion_pending()) return;
    if (!options_.m400_waits_for_rest && telemetry_.anchored.load() &&
        telemetry_.print_time_s.load() >= t_s)
      return;
    pause_for_machine();
  }
}

void MotionExecutor::drop_queued_moves() {
  planner::PlannedMove drop;
  while (queue_.try_pop(drop)) popped_.fetch_add(1, std::memory_order_release);
  if (telemetry_.anchored.load()) steps_.flush();
  publish_step_counts();
  telemetry_.anchored.store(false);
  motion_maps_held_ = false;
}

void MotionExecutor::servo_cycle(int64_t now_ns, bool cancel) {
  const double now_s = static_cast<double>(now_ns) * 1e-9;
  const bool was_anchored = telemetry_.anchored.load(std::memory_order_relaxed);
  run_cycle(now_s, cancel);
  publish_settling(now_s, was_anchored);
  if (backend_ != nullptr) {  // the device loops' reports, whether motion runs or not
    DeviceLoopReport reports[16];
    for (size_t n; (n = backend_->take_device_reports(reports, 16)) > 0;)
      for (size_t k = 0; k < n && tap_ != nullptr; ++k) tap_->on_device_loop_report(reports[k]);
    EncoderReading readings[64];
    const bool moving = telemetry_.anchored.load(std::memory_order_relaxed);
    for (size_t n; (n = backend_->take_encoder_samples(readings, 64)) > 0;)
      for (size_t k = 0; k < n; ++k) {
        EncoderReading r = readings[k];
        if (r.joint < 0 || r.joint >= kJoints) continue;
        r.mm += encoder_offset_mm_[static_cast<size_t>(r.joint)];  // the steps' frame
        if (tap_ != nullptr) tap_->on_encoder_sample(r);
        if (moving) e_t_at_encoder_sample(r.joint, r.clock, r.mm);
      }
  }
  publish_step_counts();
}

void MotionExecutor::publish_step_counts() {
  for (int j = 0; j < kJoints && j < 4; ++j)
    step_count_[static_cast<size_t>(j)].store(steps_.position_steps(j), std::memory_order_relaxed);
}

// The motion has ended (anchored went false), but the carriage has not settled yet: an open-loop
// carriage lags its deceleration by ~0.1 mm, a 21 Hz axis rings on. The tap gets the last sample
// again, with the encoders as they are now, for settle_tail_s (the recording keeps the settling).
// settling_ is raised while anchored, so the machine never looks idle between the two.
void MotionExecutor::publish_settling(double now_s, bool was_anchored) {
  if (tap_ == nullptr || options_.settle_tail_s <= 0.0) return;
  if (telemetry_.anchored.load(std::memory_order_relaxed)) {
    settling_.store(true);
    return;
  }
  if (!settling_.load(std::memory_order_relaxed)) return;
  if (was_anchored) settle_end_s_ = now_s + options_.settle_tail_s;
  if (now_s >= settle_end_s_) {
    settling_.store(false);
    return;
  }
  ServoSample s = last_sample_;
  s.host_time_s = now_s;
  for (int j = 0; j < kJoints; ++j) {
    const size_t i = static_cast<size_t>(j);
    s.encoder_mm[i] = (backend_ != nullptr ? backend_->encoder_mm(j) : NAN) + encoder_offset_mm_[i];
  }
  tap_->on_servo_sample(s);
}

void MotionExecutor::run_cycle(double now_s, bool cancel) {
  bool anchored = telemetry_.anchored.load(std::memory_order_relaxed);
  // Device loop: the MCUs hold r(t) and the steps for command_lead_s; a motion stage that woke
  // later than that (less the device's 20 ms horizon margin and a knot's 10 ms) finds them
  // braking. Named here, before the MCUs' stop reports arrive, so the message says why.
  const double gap_s = now_s - last_cycle_s_;
  last_cycle_s_ = now_s;
  if (device_loop_ && anchored && gap_s > command_lead_s() - kDeviceHorizonSlack_s && !control_fault_.load()) {
    std::snprintf(control_fault_text_, sizeof control_fault_text_,
                  "host stalled: the motion stage woke %.0f ms late, more than the %.0f ms of motion the "
                  "MCUs had queued; they stopped in a controlled stop",
                  gap_s * 1e3, (command_lead_s() - kDeviceHorizonSlack_s) * 1e3);
    control_fault_.store(true);
  }
  if (backend_ != nullptr) {
    backend_->service(now_s);
    if (backend_->fault()) {  // an MCU is gone or stopped: stop everything, resync afterwards
      drop_queued_moves();
      resync_ = true;
      const int h = homing_req_.load(std::memory_order_acquire);
      if (h == kHomingRequested || h == kHomingRunning) {  // the homing ends with the fault
        backend_->abort_homing("MCU fault");
        char msg[160];
        backend_->fault_message(msg, sizeof msg);
        std::snprintf(homing_error_, sizeof homing_error_, "homing stopped: %s", msg);
        homing_req_.store(kHomingFailed, std::memory_order_release);
      }
      return;
    }
    if (!anchored && !backend_->ready()) return;  // motion waits for the MCUs and their clocks
    // M18/M84: the drivers off at rest; on again before the next motion or homing.
    // (The request stays pending 20 ms after the message, so that the MCUs have it when M84
    // returns: in virtual time the link delivers only while the servo thread runs.)
    if (const unsigned off = motors_off_req_.load(std::memory_order_acquire);
        off != 0 && !anchored) {
      if ((motors_off_mask_ & off) != off) {
        backend_->set_motors_enabled(off, false);
        motors_off_mask_ |= off;
        motors_off_sent_s_ = now_s;
      } else if (now_s - motors_off_sent_s_ >= 0.02) {
        motors_off_req_.store(0, std::memory_order_release);
      }
    }
    if (motors_off_mask_ != 0 && motors_off_req_.load(std::memory_order_relaxed) == 0 &&
        (queue_.front() != nullptr ||
         homing_req_.load(std::memory_order_acquire) == kHomingRequested)) {
      backend_->set_motors_enabled(motors_off_mask_, true);
      motors_off_mask_ = 0;
    }
    if (const int h = homing_req_.load(std::memory_order_acquire);
        h == kHomingRequested || h == kHomingRunning) {
      homing_cycle(now_s, cancel || homing_abort_.load(std::memory_order_acquire));
      return;
    }
    if (!motion_maps_held_) {  // else the motion's clock frame (sampled_cycle) stays in force
      std::array<stepgen::TickMap, kJoints> maps;
      for (int j = 0; j < kJoints; ++j) maps[static_cast<size_t>(j)] = backend_->tick_map(j);
      steps_.set_clock_maps(maps);
    }
  }
  if (cancel || control_fault_.load(std::memory_order_relaxed)) {  // drop everything not yet turned into steps
    drop_queued_moves();
    return;
  }
  if (const int sr = stop_req_.load(std::memory_order_acquire); sr == kStopRequested || sr == kStopRunning) {
    if (sr == kStopRequested) {
      stop_req_.store(kStopRunning, std::memory_order_relaxed);
      stop_figures_ = StopFigures{};
      stop_figures_.request_s = now_s;
      if (anchored && control_) begin_stop(now_s);
    }
    if (!anchored) {  // at rest: nothing of what is queued has started
      finish_stop();
      return;
    }
  }
  if (control_) {
    sampled_cycle(now_s);
    return;
  }
  const double horizon_s = now_s + options_.lead_s;
  while (const planner::PlannedMove* front = queue_.front()) {
    if (!anchored) {  // motion starts from rest: its print time runs lead_s from now
      if (resync_) resync_to(*front);
      pa_restart(*front);
      // With the advance, the extruder starts moving half a window before the first move.
      offset_s_ = horizon_s + pa_half_window_s() - front->start_time_s;
      if (pa_active_) pa_.set_emitted_from(front->start_time_s - pa_half_window_s());
      steps_.set_time_offset_s(offset_s_);
      anchored = true;
      // Published before the first pop: a waiter (M400) must never see the queue empty and
      // the motion not yet started.
      telemetry_.anchored.store(true);
      telemetry_.anchors.fetch_add(1, std::memory_order_relaxed);
    }
    if (front->start_time_s + offset_s_ > horizon_s + pa_half_window_s()) break;
    if (pa_active_) {  // the extruder's segments come from the advance below
      emitter_.emit(*front, no_extruder_);
      pa_.push(*front);
    } else {
      emitter_.emit(*front, steps_);  // joint segments straight into step generation
    }
    executed_end_s_ = std::max(executed_end_s_, front->end_time_s() + pa_half_window_s());
    if (tap_ != nullptr) timeline_->push(*front);
    queue_.try_pop(current_);
    popped_.fetch_add(1, std::memory_order_release);
    telemetry_.segments.fetch_add(1, std::memory_order_relaxed);
  }
  if (!anchored) return;
  const double print_now_s = now_s - offset_s_;
  if (pa_active_) {
    // e_adv up to the horizon, as far as the moves known allow (half a window before their end);
    // once nothing more is queued anywhere, the rest after the last move is certain.
    const bool drained = queue_.empty() && planner_queued_.load() == 0;
    const double known_s = pa_.input_end_s() + (drained ? 1.0 : -1.0) * pa_.half_window_s();
    pa_.emit_until(std::min(print_now_s + options_.lead_s, known_s), pcfg_.servo_period_s,
                   [this](const JointSegment& s) { steps_.on_joint_segment(3, s); });
    pa_.trim_before(print_now_s);  // the telemetry below samples e_adv now
  }
  steps_.flush_due(print_now_s + options_.lead_s);
  telemetry_.print_time_s.store(print_now_s, std::memory_order_relaxed);
  if (tap_ != nullptr) {  // F = 1: the command is the plan
    control::FeedforwardInput r;
    reference(print_now_s, r);
    publish_sample(now_s, print_now_s, r.r_mm, r.r_mm, r.nozzle_mm);
  }
  // Done when nothing is queued and the last segment's time has passed on the machine.
  if (queue_.empty() && print_now_s > executed_end_s_ && planner_queued_.load() == 0) {
    steps_.flush();
    anchored = false;
    publish_step_counts();  // the counts a waiter reads once the motion has ended
  }
  telemetry_.anchored.store(anchored);
}

// e_t (thesis Sect. 5.2: e_t = |r - y|) at every encoder sample while motion runs: the joint's
// reading against the plan at the instant it shows, combined with the other joints' latest
// errors (joints on different MCUs are sampled at different instants). Every sample counts: with
// the device loop the MCUs report 10 samples at a time, and the latest of each report alone
// sampled the error at 100 Hz (a corner's transient at one or two points). With the plan read at
// the nearest command sample as well, the same path measured 0.0042-0.0080 mm in three runs where
// the device loops' own |e| agreed to 4 % (docs/decisions.md, "e_t at every encoder sample").
// The plan: the commanded samples (sampled path), or the timeline (open loop with a tap); a
// sample from before this motion's first command sample, or older than the history, is skipped.
// The sample's instant: through the motion's clock frame when one is held (the frame the device
// loops' targets and the steps were placed in: the clock sync's live estimate may be up to
// kClockFrameTolerance_s off it, 3 um at 150 mm/s), else through the live estimate.
void MotionExecutor::e_t_at_encoder_sample(int joint, int64_t mcu_clock, double enc_mm) {
  if (joint < 0 || joint > 2 || !std::isfinite(enc_mm)) return;
  const size_t i = static_cast<size_t>(joint);
  double t_s = NAN;  // servo time (sampled path) or print time (open loop)
  if (motion_maps_held_ && motion_maps_[i].ticks_per_s > 0.0)
    t_s = (static_cast<double>(mcu_clock) - motion_maps_[i].offset_ticks) /
              motion_maps_[i].ticks_per_s -
          backend_->encoder_delay_s(joint);
  else
    t_s = backend_->encoder_sample_time_s(joint, mcu_clock) - offset_s_;
  if (!std::isfinite(t_s)) return;
  double r_mm = NAN;
  if (control_) {
    // r between the two command samples around the instant (the samples are one servo period
    // apart and the encoders sample at their own phase: the nearer sample alone would be up to
    // half a period off, 75 um at 150 mm/s, by an amount that changes with every motion's phase).
    if (sample_no_ == 0) return;
    const size_t cap = history_.size();
    uint64_t n = sample_no_;
    while (n > 0 && history_[n % cap].t_s > t_s) {
      if (sample_no_ - n + 2 >= cap) return;  // older than the history holds
      --n;
    }
    const Sample& a = history_[n % cap];
    if (n == 0 && t_s < a.t_s) return;  // before the motion's first command sample
    r_mm = a.r_mm[i];
    if (n < sample_no_) {
      const Sample& b = history_[(n + 1) % cap];
      if (b.t_s > a.t_s) r_mm += (t_s - a.t_s) / (b.t_s - a.t_s) * (b.r_mm[i] - a.r_mm[i]);
    }
  } else {
    if (tap_ == nullptr) return;  // no timeline to read the plan from
    control::FeedforwardInput r;
    if (!reference(t_s, r)) return;
    r_mm = r.r_mm[i];
  }
  last_e_mm_[i] = r_mm - enc_mm;
  has_e_[i] = true;
  add_e_t_sample();
}

// e_t = |r - y| over the joints' latest errors (thesis Sect. 5.2), into the status counters.
void MotionExecutor::add_e_t_sample() {
  double sq = 0.0;
  for (size_t i = 0; i < 3; ++i)
    if (has_e_[i]) sq += last_e_mm_[i] * last_e_mm_[i];
  const double e_t = std::sqrt(sq);
  e_t_sum_mm_.store(e_t_sum_mm_.load(std::memory_order_relaxed) + e_t, std::memory_order_relaxed);
  if (e_t > e_t_max_mm_.load(std::memory_order_relaxed))
    e_t_max_mm_.store(e_t, std::memory_order_relaxed);
  e_t_samples_.fetch_add(1, std::memory_order_relaxed);
}

// Planner thread (Machine::flush): the stop requested, the lookahead released (each of its motions
// ends at rest: the moves the servo thread takes while slowing down end where the plan could stop),
// then the wait for the rest point, from which the interpreter continues.
void MotionExecutor::flush_motion(const std::atomic<bool>& cancel) {
  struct Waiting {
    std::atomic<bool>& w;
    explicit Waiting(std::atomic<bool>& f) : w(f) { w = true; }
    ~Waiting() { w = false; }
  } waiting(waiting_);
  stop_released_.store(false);
  stop_req_.store(kStopRequested, std::memory_order_release);
  planner_.flush();
  planner_queued_.store(planner_.queued());
  stop_released_.store(true, std::memory_order_release);
  while (stop_req_.load(std::memory_order_acquire) != kStopDone) {
    if (cancel.load() || faulted()) {  // stopped otherwise: the servo thread drops it all
      stop_req_.store(kNoStop);
      return;
    }
    pause_for_machine();
  }
  if (stop_pos_valid_) {
    interp_->set_machine_position(stop_pos_mm_);
    std::lock_guard<std::mutex> lock(objects_mu_);
    objects_ = interp_->objects();
  }
  stop_req_.store(kNoStop, std::memory_order_release);
}

// Servo thread: the plan at plan (print) time plan_s, E through the pressure advance when it runs
// (its time keeps its offset to the plan's: plan_shift_s_ - pa_base_shift_s_).
bool MotionExecutor::reference_plan(double plan_s, control::FeedforwardInput& out) const {
  planner::CartesianSample c;
  const bool covered = timeline_->sample(plan_s, c);
  if (timeline_->size() == 0) return false;
  out = input_at(c);
  if (pa_active_) out.r_mm[3] = pa_.position_mm(plan_s + plan_shift_s_ - pa_base_shift_s_);
  return covered;
}

namespace {
// Path speed of a planned state: XYZ, or E alone for an E-only move.
double path_speed_mm_s(const planner::CartesianSample& c) {
  const double v = std::sqrt(c.vel_mm_s[0] * c.vel_mm_s[0] + c.vel_mm_s[1] * c.vel_mm_s[1] +
                             c.vel_mm_s[2] * c.vel_mm_s[2]);
  return v > 1e-9 ? v : std::fabs(c.vel_mm_s[3]);
}
}  // namespace

// Servo thread: the stop starts after the samples already commanded (the MCUs hold them: with the
// device loop lead_s + 35 ms of r(t) and steps); the feedforward has seen the plan P samples
// further (its preview), so the slowing starts at its input, the preview front.
void MotionExecutor::begin_stop(double now_s) {
  const double period_s = pcfg_.servo_period_s;
  const int preview = control_->preview_samples();
  const size_t n = stop_tau_.size();
  const double tau_now = next_sample_s_ - plan_shift_s_;
  for (int i = 0; i <= preview; ++i)
    stop_tau_[(sample_no_ + static_cast<uint64_t>(i)) % n] = tau_now + i * period_s;
  stop_lead_plan_s_ = tau_now + preview * period_s;
  stop_start_plan_s_ = stop_lead_plan_s_;
  planner::CartesianSample c;
  timeline_->sample(stop_lead_plan_s_, c);
  stop_cap_mm_s_ = path_speed_mm_s(c);
  stop_warping_ = true;
  stop_frozen_ = false;
  stop_figures_.warped = true;
  stop_figures_.speed_mm_s = stop_cap_mm_s_;
  stop_figures_.decel_mm_s2 = pcfg_.max_accel_mm_s2;
  stop_figures_.begin_s = next_sample_s_ + offset_s_;
  (void)now_s;
}

// Servo thread, one command sample at servo time t_s while stopping: the preview front's plan
// time advances by lambda T, lambda = min(1, cap / v(tau)) where the cap falls by a T per sample,
// so the commanded path speed lambda v falls at a (the time-scaled path r(tau(t)) has tangential
// acceleration d(lambda v)/dt = -a and its normal acceleration scaled by lambda^2, so it stays
// within the limits the plan met). a: the planner's max_accel_mm_s2, less where an axis's own
// limit along the path's direction is lower. At cap 0 (or where the plan itself is at rest) the
// plan time stands: the rest point. Sets plan_shift_s_ for t_s; returns the preview front's plan
// time (the feedforward's input).
double MotionExecutor::stop_step(double t_s) {
  const double period_s = pcfg_.servo_period_s;
  const int preview = control_->preview_samples();
  const size_t n = stop_tau_.size();
  const uint64_t k = sample_no_ + 1;  // this sample's number
  if (!stop_frozen_) {
    planner::CartesianSample c;
    timeline_->sample(stop_lead_plan_s_, c);
    const double v = path_speed_mm_s(c);
    double a = pcfg_.max_accel_mm_s2;
    for (size_t i = 0; i < 4; ++i) {
      const double vi = std::fabs(c.vel_mm_s[i]);
      if (vi > 1e-9 && v > 1e-9) a = std::min(a, pcfg_.max_axis_accel_mm_s2[i] * v / vi);
    }
    stop_figures_.decel_mm_s2 = std::min(stop_figures_.decel_mm_s2, a);
    bool rest = false;
    double lambda = 1.0;
    if (v <= 1e-9) {
      rest = stop_lead_plan_s_ > stop_start_plan_s_;  // the plan stands still here: stop here
      if (rest) lambda = 0.0;
    } else if (v > stop_cap_mm_s_) {
      lambda = std::max(0.0, stop_cap_mm_s_ / v);
    }
    const double before_s = stop_lead_plan_s_;
    stop_lead_plan_s_ += lambda * period_s;
    stop_cap_mm_s_ -= a * period_s;
    if (stop_lead_plan_s_ > before_s) {
      planner::CartesianSample p0, p1;
      timeline_->sample(before_s, p0);
      timeline_->sample(stop_lead_plan_s_, p1);
      double d2 = 0.0;
      for (size_t i = 0; i < 3; ++i) d2 += (p1.pos_mm[i] - p0.pos_mm[i]) * (p1.pos_mm[i] - p0.pos_mm[i]);
      stop_figures_.path_mm += std::sqrt(d2);
    }
    if (rest || stop_cap_mm_s_ <= 0.0) {
      stop_frozen_ = true;
      // The sample whose plan time is the rest point: P samples on (the preview), then the hold.
      const bool pi_loop = control_->closed_loop() || device_loop_;
      stop_end_s_ = t_s + preview * period_s + (pi_loop ? options_.control_settle_s : 0.0) +
                    pa_half_window_s();
      stop_figures_.rest_s = t_s + preview * period_s + offset_s_;
      control::FeedforwardInput at;
      reference_plan(stop_lead_plan_s_, at);
      planner::CartesianSample c_rest;
      timeline_->sample(stop_lead_plan_s_, c_rest);
      for (size_t i = 0; i < 4; ++i) stop_pos_mm_[i] = c_rest.pos_mm[i];
      stop_pos_mm_[3] = at.r_mm[3];  // E as commanded (with the advance, e_adv)
      stop_pos_valid_ = true;
      for (size_t i = 0; i < 4; ++i) stop_figures_.position_mm[i] = stop_pos_mm_[i];
    }
  }
  stop_tau_[(k + static_cast<uint64_t>(preview)) % n] = stop_lead_plan_s_;
  const double shift_s = t_s - stop_tau_[k % n];
  pa_base_shift_s_ += shift_s - plan_shift_s_;  // the advance's time stands with the plan's
  plan_shift_s_ = shift_s;
  return stop_lead_plan_s_;
}

// Servo thread, the machine at rest with a stop requested: once the planner has released all it
// held, the moves not executed are dropped; where the carriage rests is the stop's rest point, or
// (nothing had started) the first dropped move's start.
void MotionExecutor::finish_stop() {
  if (!stop_released_.load(std::memory_order_acquire)) return;
  planner::PlannedMove drop;
  while (queue_.try_pop(drop)) {
    if (!stop_pos_valid_) {
      stop_pos_mm_ = drop.start_mm;
      stop_pos_valid_ = true;
    }
    ++stop_figures_.moves_dropped;
    popped_.fetch_add(1, std::memory_order_release);
  }
  timeline_->clear();
  stop_warping_ = false;
  stop_frozen_ = false;
  executed_end_s_ = 0.0;
  if (stop_pos_valid_)
    for (size_t i = 0; i < 4; ++i) stop_figures_.position_mm[i] = stop_pos_mm_[i];
  stop_req_.store(kStopDone, std::memory_order_release);
}

// After power-on or a fault: the joints restart from the plan (the steps queued before were not
// all executed), and the encoders are re-referenced to it.
void MotionExecutor::resync_to(const planner::PlannedMove& front) {
  const planner::Joints q = kin_->inverse({front.start_mm[0], front.start_mm[1], front.start_mm[2]});
  for (int j = 0; j < 3; ++j) steps_.set_position_mm(j, q[static_cast<size_t>(j)]);
  steps_.set_position_mm(3, front.start_mm[3]);
  for (int j = 0; j < kJoints; ++j) {
    const double pos = j < 3 ? q[static_cast<size_t>(j)] : front.start_mm[3];
    const double enc = backend_ != nullptr ? backend_->encoder_mm(j) : NAN;
    encoder_offset_mm_[static_cast<size_t>(j)] = pos - (std::isfinite(enc) ? enc : 0.0);
    last_command_mm_[static_cast<size_t>(j)] = pos;
  }
  resync_ = false;
}

// The plan at print time t_s: joint positions through the kinematics, and the nozzle. False when
// no planned move covers t_s (before the first, in a gap, after the last: the nearest end).
bool MotionExecutor::reference(double t_s, control::FeedforwardInput& out) const {
  planner::CartesianSample c;
  const bool covered = timeline_->sample(t_s - plan_shift_s_, c);
  if (timeline_->size() == 0) return false;
  out = input_at(c);
  if (pa_active_) out.r_mm[3] = pa_.position_mm(t_s - pa_base_shift_s_);  // e_adv
  return covered;
}

// A planned Cartesian state as the feedforward's input: joints through the kinematics, nozzle.
control::FeedforwardInput MotionExecutor::input_at(const planner::CartesianSample& c) const {
  control::FeedforwardInput out;
  const planner::Joints q = kin_->inverse({c.pos_mm[0], c.pos_mm[1], c.pos_mm[2]});
  for (int j = 0; j < 3; ++j) out.r_mm[static_cast<size_t>(j)] = q[static_cast<size_t>(j)];
  out.r_mm[3] = c.pos_mm[3];
  for (int i = 0; i < 3; ++i) out.nozzle_mm[static_cast<size_t>(i)] = c.pos_mm[static_cast<size_t>(i)];
  return out;
}

void MotionExecutor::publish_sample(double now_s, double print_time_s, const control::JointArray& desired_mm,
                                    const control::JointArray& command_mm, const std::array<double, 3>& nozzle_mm) {
  ServoSample s;
  s.host_time_s = now_s;
  s.print_time_s = print_time_s;
  s.desired_mm = desired_mm;
  s.command_mm = command_mm;
  s.nozzle_mm = nozzle_mm;
  for (int j = 0; j < kJoints; ++j) {
    const size_t i = static_cast<size_t>(j);
    const double enc = backend_ != nullptr ? backend_->encoder_mm(j) : NAN;
    s.encoder_mm[i] = enc + encoder_offset_mm_[i];
    const double spm = steps_.params().steps_per_mm[i];
    s.steps_mm[i] = spm > 0.0 ? static_cast<double>(steps_.position_steps(j)) / spm : NAN;
  }
  last_sample_ = s;
  tap_->on_servo_sample(s);
}

// Motion starts from rest on the sampled path: the first command sample is the first move's
// start, control_lead_s from now.
void MotionExecutor::start_sampled(const planner::PlannedMove& first, double now_s) {
  stop_warping_ = false;
  stop_frozen_ = false;
  // The first move's start, at rest: the reference every filter starts from.
  const control::FeedforwardInput at = input_at(planner::sample_move(first, first.start_time_s));
  if (resync_) {
    resync_to(first);
    control_->reset_all(at);
  }
  next_sample_s_ = first.start_time_s + plan_shift_s_;  // servo time (monotonic across stops)
  offset_s_ = now_s + command_lead_s() - next_sample_s_;
  // Pressure advance: the extruder starts moving half a window before the first move, so the plan
  // starts that much later; pa time = servo time - pa_base_shift_s_ = plan time from here.
  pa_restart(first);
  plan_shift_s_ += pa_half_window_s();
  pa_base_shift_s_ = plan_shift_s_;
  steps_.set_time_offset_s(offset_s_);
  if (device_loop_) hold_clock_frame(next_sample_s_);
  control_->reset_feedforward(at);
  has_e_ = {};  // e_t restarts from this motion's encoder reports
  prime_pending_ = true;  // the preview fills once the moves are on the timeline (sampled_cycle)
  // The motor is where the steps put it; the correction the PI holds is part of that.
  sample_no_ = 0;
  model_next_ = 0;
  model_t_s_ = next_sample_s_ - pcfg_.servo_period_s;
  Sample& s0 = history_[0];
  s0.t_s = next_sample_s_;
  s0.plan_s = next_sample_s_ - plan_shift_s_;
  s0.r_mm = at.r_mm;
  s0.nozzle_mm = at.nozzle_mm;
  s0.u_ff_mm = at.r_mm;
  s0.u_mm = last_command_mm_;
}

// The host loop's feedback (control.loop: host): the lost-step model advanced over every command
// sample executed since the previous cycle, one per servo period of executed time (a hold of the
// plan repeats its held command), then the PI on the encoders' time-stamped samples. False when
// the control law stopped motion (the fault is latched and named).
bool MotionExecutor::host_feedback(double now_s, uint64_t n_enc, double enc_time_s,
                                   const control::JointArray& enc, const std::array<bool, 4>& fresh) {
  const size_t cap = history_.size();
  const double period_s = pcfg_.servo_period_s;
  // The lost-step detector's model has no friction or weight: it gets the commands without the
  // share those loads take up.
  auto executed = [](const Sample& x) {
    ServoControl::ExecutedSample e;
    e.desired_mm = x.r_mm;
    for (size_t i = 0; i < e.motor_mm.size(); ++i) {
      e.expected_lead_mm[i] = x.u_ff_mm[i] - x.load_mm[i] - x.r_mm[i];
      e.motor_mm[i] = x.u_mm[i] - x.load_mm[i];
    }
    return e;
  };
  // The ring holds the last `cap` samples: after a longer stall the model goes on from the oldest.
  const uint64_t oldest = sample_no_ + 1 > cap ? sample_no_ + 1 - cap : 0;
  if (model_next_ < oldest) {
    model_next_ = oldest;
    model_t_s_ = history_[oldest % cap].t_s - period_s;
  }
  // One model step per period up to the encoders' sampling time: the sample due then, or within a
  // pause of the plan (a late cycle's hold) the held one.
  for (size_t guard = 0; guard < cap + 10000; ++guard) {
    const double t = model_t_s_ + period_s;
    if (t > enc_time_s + 0.5 * period_s) break;
    if (model_next_ <= sample_no_ && history_[model_next_ % cap].t_s <= t + 0.5 * period_s) {
      const Sample& x = history_[model_next_ % cap];
      control_->advance_model(executed(x));
      model_t_s_ = x.t_s;
      ++model_next_;
    } else if (model_next_ > oldest) {
      control_->advance_model(executed(history_[(model_next_ - 1) % cap]));
      model_t_s_ = t;
    } else {
      break;
    }
  }
  const Sample& at_enc = history_[n_enc % cap];
  ServoControl::FeedbackInput in;
  in.now_s = now_s;
  in.print_time_s = at_enc.plan_s;  // events at the plan time the encoders were sampled at
  in.desired_mm = at_enc.r_mm;
  in.encoder_mm = enc;
  in.fresh = fresh;
  for (int j = 0; j < kJoints; ++j)
    in.sample_time_s[static_cast<size_t>(j)] = backend_ != nullptr ? backend_->encoder_time_s(j) : NAN;
  ServoEvent ev;
  bool has_event = false;
  const bool ok = control_->update_feedback(in, &ev, &has_event);
  if (has_event && tap_ != nullptr) tap_->on_servo_event(ev);
  if (has_event) lost_step_events_.fetch_add(1, std::memory_order_relaxed);
  if (!ok) {
    std::snprintf(control_fault_text_, sizeof control_fault_text_, "%s", control_->fault_text());
    control_fault_.store(true);
    if (tap_ != nullptr) tap_->on_servo_event(ev);
    drop_queued_moves();
    resync_ = true;
    return false;
  }
  return true;
}

// The frame through the clock sync's estimate `live` (host time -> ticks) at servo time t_s: servo
// time -> ticks, t_s on a whole tick, the rate rounded to whole ticks per second (1 Hz: 0.014 ppm
// of a 72 MHz clock; the 20 us tolerance only after 20 minutes). Two estimates a fraction of a
// hertz apart (the clock sync's noise) then give the same frame, and the frame is kept in servo
// time, whose values are the same in every run: host time's large values would cost each tick
// its last thousandth, differently in every run, and flip a step's rounding here and there.
stepgen::TickMap MotionExecutor::frame_through(const stepgen::TickMap& live, double t_s) const {
  stepgen::TickMap m;
  m.ticks_per_s = std::round(live.ticks_per_s);
  m.offset_ticks = std::round(live.ticks(t_s + offset_s_)) - m.ticks_per_s * t_s;
  return m;
}

// The motion's clock frame (motion_executor.hpp), from its first sample at servo time t0_s.
void MotionExecutor::hold_clock_frame(double t0_s) {
  for (int j = 0; j < kJoints; ++j) {
    const stepgen::TickMap frame = frame_through(backend_->tick_map(j), t0_s);
    motion_maps_[static_cast<size_t>(j)] = frame;
    motion_start_clock_[static_cast<size_t>(j)].store(std::llround(frame.ticks(t0_s)), std::memory_order_relaxed);
  }
  steps_.set_print_maps(motion_maps_);
  motion_maps_held_ = true;
}

// Replaces a joint's frame when the clock sync's estimate at servo time t_s has moved more than
// the tolerance away from it (an MCU clock drifting from its estimated rate, a better estimate):
// a step of at most that size in the joint's timing, then the frame holds again.
void MotionExecutor::refresh_clock_frame(double t_s) {
  bool changed = false;
  for (int j = 0; j < kJoints; ++j) {
    const stepgen::TickMap live = backend_->tick_map(j);
    stepgen::TickMap& held = motion_maps_[static_cast<size_t>(j)];
    if (std::fabs(live.ticks(t_s + offset_s_) - held.ticks(t_s)) <= kClockFrameTolerance_s * live.ticks_per_s)
      continue;
    held = frame_through(live, t_s);
    changed = true;
  }
  if (!changed) return;
  steps_.set_print_maps(motion_maps_);
  clock_frame_refreshes_.fetch_add(1, std::memory_order_relaxed);
}

void MotionExecutor::sampled_cycle(double now_s) {
  device_loop_ = false;
  for (int j = 0; backend_ != nullptr && j < kJoints; ++j) device_loop_ = device_loop_ || backend_->device_loop(j);
  const double period_s = pcfg_.servo_period_s;
  const int preview = control_->preview_samples();
  const double lead_s = command_lead_s();
  bool anchored = telemetry_.anchored.load(std::memory_order_relaxed);
  if (!anchored) {
    const planner::PlannedMove* front = queue_.front();
    if (front == nullptr) return;
    start_sampled(*front, now_s);
    anchored = true;
    telemetry_.anchored.store(true);  // before the first pop (see run_cycle)
    telemetry_.anchors.fetch_add(1, std::memory_order_relaxed);
  }
  const double print_now_s = now_s - offset_s_;
  // Moves into the timeline as far as this cycle's newest sample and its preview reach.
  // The pressure advance needs the plan half a window (h) further.
  const double pa_h_s = pa_half_window_s();
  const double need_s = print_now_s + lead_s + (preview + 2) * period_s + pa_h_s;
  while (const planner::PlannedMove* front = queue_.front()) {
    if (front->start_time_s + plan_shift_s_ > need_s) break;
    const planner::PlannedMove& m = *front;
    // A move planned after the plan had run out while the loop was still holding the position:
    // the plan's clock stood still meanwhile, so the rest of the plan moves later by the gap.
    // With the advance, later still: e_adv up to the newest sample (and its preview) assumed rest
    // after the plan's end; a move starting at s changes e_adv from s - h on.
    const double pa_late_s = pa_active_ ? pa_h_s + preview * period_s : 0.0;
    if (!stop_warping_ && m.start_time_s + plan_shift_s_ < next_sample_s_ + pa_late_s - 1e-9)
      plan_shift_s_ = next_sample_s_ + pa_late_s - m.start_time_s;
    if (pa_active_) pa_.push(m, plan_shift_s_ - pa_base_shift_s_);
    timeline_->push(m);  // in plan time
    executed_end_s_ = std::max(executed_end_s_, m.end_time_s());  // plan time
    queue_.try_pop(current_);
    popped_.fetch_add(1, std::memory_order_release);
    telemetry_.segments.fetch_add(1, std::memory_order_relaxed);
  }
  if (prime_pending_) {
    // The feedforward was reset at rest (as if at t0 - P T); its preview now takes in the plan
    // r(t0 + T) .. r(t0 + P T) (outputs discarded: they are for t0 - P T + T .. t0, at rest).
    // The next step() then gets r(t0 + (P + 1) T) and returns u for t0 + T.
    for (int i = 1; i <= preview; ++i) {
      control::FeedforwardInput ahead;
      reference(next_sample_s_ + i * period_s, ahead);
      control::JointArray u_ff{}, u{};
      control_->command(ahead, u_ff, u);
    }
    prime_pending_ = false;
  }
  // Feedback: the encoders now against the samples commanded for now.
  const size_t cap = history_.size();
  uint64_t n_now = sample_no_;
  while (n_now > 0 && history_[n_now % cap].t_s > print_now_s + 1e-9 && sample_no_ - n_now + 1 < cap) --n_now;
  const Sample& at_now = history_[n_now % cap];
  // The encoders were sampled a little earlier (sampling period, report latency): compare them
  // with the plan at the instant they were sampled, or a velocity-proportional bias would reach
  // the PI (100 mm/s x 1 ms = 0.1 mm).
  uint64_t n_enc = n_now;
  double print_enc_s = NAN;  // when the encoders were sampled (servo time), if known
  if (backend_ != nullptr) {
    double t_enc_s = NAN;
    for (int j = 0; j < kJoints; ++j) {
      const double t = backend_->encoder_time_s(j);
      if (std::isfinite(t) && !(t >= t_enc_s)) t_enc_s = t;  // the oldest reading
    }
    if (std::isfinite(t_enc_s)) {
      print_enc_s = t_enc_s - offset_s_;
      while (n_enc > 0 && history_[n_enc % cap].t_s > print_enc_s + 0.5 * period_s && sample_no_ - n_enc + 2 < cap)
        --n_enc;
    }
  }
  const Sample& at_enc = history_[n_enc % cap];
  control::JointArray enc{};
  std::array<bool, 4> fresh{};
  for (int j = 0; j < kJoints; ++j) {
    const size_t i = static_cast<size_t>(j);
    const double e = backend_ != nullptr ? backend_->encoder_mm(j) : NAN;
    enc[i] = e + encoder_offset_mm_[i];
    const unsigned long long reports = backend_ != nullptr ? backend_->encoder_reports(j) : 0;
    fresh[i] = reports != encoder_reports_seen_[i];
    encoder_reports_seen_[i] = reports;
  }
  if (control_->closed_loop() &&
      !host_feedback(now_s, n_enc, std::isfinite(print_enc_s) ? print_enc_s : at_enc.t_s, enc, fresh))
    return;
  // Command samples up to control_lead_s ahead: u = F(r) + C(e), one linear segment per period;
  // after the plan's end (and the feedforward's preview), the loop holds the position for
  // control_settle_s more (the PI removes what is left of the error), then stops.
  bool plan_empty = queue_.empty() && planner_queued_.load() == 0;
  // Closed loop, the loop holds the position for control_settle_s after the plan's end (thesis
  // Sect. 5.1: the integrator needs ~400 ms) before the motion counts as done; on the device loop
  // r(t) ends on that flat piece (longer than the device's 20 ms horizon margin, or the last
  // decelerating knots would read as r running out while it moves).
  const bool pi_loop = control_->closed_loop() || device_loop_;
  const double hold_s = pi_loop ? options_.control_settle_s : 0.0;
  double stop_s = executed_end_s_ + plan_shift_s_ + preview * period_s + hold_s +
                  pa_half_window_s();  // servo time (the extruder's advance ends h later)
  if (stop_frozen_) {  // a flush's rest point: the plan ends there (the moves after are dropped)
    plan_empty = true;
    stop_s = stop_end_s_;
  }
  // A late cycle (the thread woke more than the lead late, on a machine without real-time
  // scheduling): the samples still to come would be due in the past, and steps in the past stop
  // the MCU (queue underrun). Instead the plan pauses: the motor holds its last command over the
  // gap and the plan resumes a quarter of the lead from now, and no sooner than two periods from
  // now (the steps computed now reach the MCU with the next cycle's I/O: with a 2 ms lead, a
  // quarter of it left steps due before they arrived). Counted in late_cycles.
  const double earliest_s = print_now_s + std::min(lead_s, std::max(0.25 * lead_s, 2.0 * period_s));
  const bool commanding = !(plan_empty && next_sample_s_ >= stop_s);
  if (device_loop_ && commanding && next_sample_s_ + period_s < print_now_s) {
    // The PI runs on the MCUs, which had r(t) and the steps for lead_s: a stall shorter than that
    // changed nothing. This one was longer: r ran out on the MCUs, which stopped in a controlled
    // stop (LOOP_EVENT "target horizon"); nothing jumps, the recording keeps the run.
    std::snprintf(control_fault_text_, sizeof control_fault_text_,
                  "host stalled: the motion stage ran %.0f ms late, more than the %.0f ms the MCUs "
                  "had queued; they stopped in a controlled stop",
                  (print_now_s - next_sample_s_) * 1e3 + lead_s * 1e3, lead_s * 1e3);
    control_fault_.store(true);
    drop_queued_moves();
    resync_ = true;
    return;
  }
  if (!device_loop_ && commanding && next_sample_s_ + period_s < earliest_s - 1e-9) {
    const double gap_s = earliest_s - (next_sample_s_ + period_s);
    const Sample& last = history_[sample_no_ % cap];
    for (int j = 0; j < kJoints; ++j) {
      if (steps_.params().steps_per_mm[static_cast<size_t>(j)] <= 0.0) continue;
      JointSegment hold;
      hold.t0_s = next_sample_s_;
      hold.duration_s = gap_s;
      hold.c0_mm = last.u_mm[static_cast<size_t>(j)];
      steps_.on_joint_segment(j, hold);
    }
    next_sample_s_ += gap_s;
    plan_shift_s_ += gap_s;
    pa_base_shift_s_ += gap_s;  // the extruder's advance pauses with the plan
    late_cycles_.fetch_add(1, std::memory_order_relaxed);
  }
  while (next_sample_s_ + period_s <= print_now_s + lead_s + 1e-9 && !(plan_empty && next_sample_s_ >= stop_s)) {
    const double t_s = next_sample_s_ + period_s;
    if (device_loop_) refresh_clock_frame(t_s);
    control::FeedforwardInput ahead;
    if (stop_warping_)
      reference_plan(stop_step(t_s), ahead);
    else
      reference(t_s + preview * period_s, ahead);
    control::JointArray u_ff{}, u{};
    control_->command(ahead, u_ff, u);
    const Sample& prev = history_[sample_no_ % cap];
    for (int j = 0; j < kJoints; ++j) {
      const size_t i = static_cast<size_t>(j);
      if (steps_.params().steps_per_mm[i] <= 0.0) continue;
      JointSegment seg;
      seg.t0_s = t_s - period_s;
      seg.duration_s = period_s;
      seg.c0_mm = prev.u_mm[i];
      seg.c1_mm_s = (u[i] - prev.u_mm[i]) / period_s;
      steps_.on_joint_segment(j, seg);
    }
    ++sample_no_;
    Sample& s = history_[sample_no_ % cap];
    control::FeedforwardInput now_ref;
    reference(t_s, now_ref);
    s.t_s = t_s;
    s.plan_s = t_s - plan_shift_s_;
    s.r_mm = now_ref.r_mm;
    // What the command aims at: the feedback compares the encoders with it (a smoothed velocity
    // jump is the feedforward's reference there, not the plan's corner).
    control::JointArray target{};
    if (control_->feedforward_target(target))
      for (int j = 0; j < 3; ++j) s.r_mm[static_cast<size_t>(j)] = target[static_cast<size_t>(j)];
    if (!control_->feedforward_load(s.load_mm)) s.load_mm = control::JointArray{};
    s.nozzle_mm = now_ref.nozzle_mm;
    s.u_ff_mm = u_ff;
    s.u_mm = u;
    last_command_mm_ = u;
    next_sample_s_ = t_s;
    if (device_loop_) {  // r(t) to the MCUs' loops, in the encoders' frame, in the clock frame
      for (int j = 0; j < kJoints; ++j) {
        const size_t i = static_cast<size_t>(j);
        if (!backend_->device_loop(j)) continue;
        const auto clock = static_cast<int64_t>(std::llround(motion_maps_[i].ticks(t_s)));
        backend_->queue_target(j, clock, s.r_mm[i] - encoder_offset_mm_[i]);
      }
      // The steps' runs close on the sample grid, not where this cycle happened to wake: the
      // same plan gives the same step ticks however the host was scheduled.
      steps_.flush_due(t_s);
    }
  }
  if (pa_active_) pa_.trim_before(next_sample_s_ - pa_base_shift_s_);
  if (device_loop_) {
    backend_->flush_targets(/*end_of_motion=*/plan_empty && next_sample_s_ >= stop_s);
    ServoEvent events[8];
    const size_t n = backend_->take_device_events(events, 8);
    for (size_t k = 0; k < n && tap_ != nullptr; ++k) {
      events[k].print_time_s -= offset_s_ + plan_shift_s_;  // host time -> print time
      tap_->on_servo_event(events[k]);
    }
  }
  if (!device_loop_) steps_.flush_due(print_now_s + lead_s);
  // Print time as the planner counts it: it stands at the plan's end while the loop holds.
  const double print_plan_s = plan_empty ? std::min(print_now_s - plan_shift_s_, executed_end_s_)
                                         : print_now_s - plan_shift_s_;
  telemetry_.print_time_s.store(print_plan_s, std::memory_order_relaxed);
  // The sample's plan time: that of the command in effect now (while a late cycle's pause holds
  // a command, the plan time of the held one; print_now_s less the new shift would run ahead).
  if (tap_ != nullptr)
    publish_sample(now_s, at_now.plan_s + std::min(print_now_s - at_now.t_s, period_s), at_now.r_mm,
                   at_now.u_mm, at_now.nozzle_mm);
  // Done when everything planned has been commanded (with the feedforward's preview drained and
  // the hold over) and executed.
  if (plan_empty && next_sample_s_ >= stop_s && print_now_s >= next_sample_s_) {
    steps_.flush();
    anchored = false;
    motion_maps_held_ = false;
    publish_step_counts();  // the counts a waiter reads once the motion has ended
  }
  telemetry_.anchored.store(anchored);
}

}  // namespace feedloop::engine
