#include "engine/motion_executor.hpp"

#include <algorithm>  // std::max
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
  if (motion) wait_for_room(cancel);
  Status st = interp_->execute(cmd);
  planner_queued_.store(planner_.queued());
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
  const bool running_dry =
      telemetry_.anchored.load() && planned_end_s_.load() - executing_print_time_s() < 2.0 * options_.lead_s;
  if (running_dry || quiet > std::chrono::duration<double>(options_.input_pause_flush_s)) planner_.flush();
  planner_queued_.store(planner_.queued());
}

bool MotionExecutor::motion_pending() const {
  return planner_queued_.load() > 0 || pushed_.load() != popped_.load() ||
         telemetry_.anchored.load(std::memory_order_relaxed);
}

void MotionExecutor::motion_status(MachineStatus& s) const {
  s.moving = telemetry_.anchored.load(std::memory_order_relaxed);
  s.print_time_s = telemetry_.print_time_s.load(std::memory_order_relaxed);
  s.planned_until_s = planned_end_s_.load(std::memory_order_relaxed);
  s.moves_planned = moves_emitted_.load(std::memory_order_relaxed);
  s.segments_queued = pushed_.load() - popped_.load();
  s.motion_starts = telemetry_.anchors.load(std::memory_order_relaxed);
  if (backend_ != nullptr) {  // the MCUs: encoder positions, and a fault naming the MCU
    for (int j = 0; j < 4; ++j) s.encoder_mm[j] = backend_->encoder_mm(j);
    s.encoder_samples = backend_->encoder_samples();
    if (backend_->fault()) backend_->fault_message(s.last_error, sizeof s.last_error);
  }
}

void MotionExecutor::on_move(const planner::PlannedMove& m) {
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
}

double MotionExecutor::executing_print_time_s() const {
  return telemetry_.anchored.load(std::memory_order_relaxed)
             ? telemetry_.print_time_s.load(std::memory_order_relaxed)
             : idle_base_s_.load(std::memory_order_relaxed);
}

// Virtual time may run on while enough planned motion lies ahead, or when the planner holds
// nothing back; never into moves the lookahead has not released yet.
bool MotionExecutor::may_advance_virtual(bool planner_busy) const {
  if (waiting_.load()) return true;  // M400 flushed everything and waits for the machine
  if (planned_end_s_.load() - executing_print_time_s() > options_.lead_s + 0.01) return true;
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
    if (telemetry_.anchored.load() && telemetry_.print_time_s.load() >= t_s) return;
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
}

void MotionExecutor::drop_queued_moves() {
  planner::PlannedMove drop;
  while (queue_.try_pop(drop)) popped_.fetch_add(1, std::memory_order_release);
  if (telemetry_.anchored.load()) steps_.flush();
  telemetry_.anchored.store(false);
}

void MotionExecutor::servo_cycle(int64_t now_ns, bool cancel) {
  const double now_s = static_cast<double>(now_ns) * 1e-9;
  bool anchored = telemetry_.anchored.load(std::memory_order_relaxed);
  if (backend_ != nullptr) {
    backend_->service(now_s);
    if (backend_->fault()) {  // an MCU is gone or stopped: stop everything, resync afterwards
      drop_queued_moves();
      resync_ = true;
      return;
    }
    if (!anchored && !backend_->ready()) return;  // motion waits for the MCUs and their clocks
    std::array<stepgen::TickMap, kJoints> maps;
    for (int j = 0; j < kJoints; ++j) maps[static_cast<size_t>(j)] = backend_->tick_map(j);
    steps_.set_clock_maps(maps);
  }
  if (cancel) {  // drop everything not yet turned into steps
    drop_queued_moves();
    return;
  }
  const double horizon_s = now_s + options_.lead_s;
  while (const planner::PlannedMove* front = queue_.front()) {
    if (!anchored) {  // motion starts from rest: its print time runs lead_s from now
      if (resync_) {  // after a fault the steps sent were not all executed: restart from the plan
        const planner::Joints q = kin_->inverse({front->start_mm[0], front->start_mm[1], front->start_mm[2]});
        for (int j = 0; j < 3; ++j) steps_.set_position_mm(j, q[static_cast<size_t>(j)]);
        steps_.set_position_mm(3, front->start_mm[3]);
        resync_ = false;
      }
      offset_s_ = horizon_s - front->start_time_s;
      steps_.set_time_offset_s(offset_s_);
      anchored = true;
      telemetry_.anchors.fetch_add(1, std::memory_order_relaxed);
    }
    if (front->start_time_s + offset_s_ > horizon_s) break;
    emitter_.emit(*front, steps_);  // joint segments straight into step generation
    executed_end_s_ = std::max(executed_end_s_, front->end_time_s());
    queue_.try_pop(current_);
    popped_.fetch_add(1, std::memory_order_release);
    telemetry_.segments.fetch_add(1, std::memory_order_relaxed);
  }
  if (!anchored) return;
  const double print_now_s = now_s - offset_s_;
  steps_.flush_due(print_now_s + options_.lead_s);
  telemetry_.print_time_s.store(print_now_s, std::memory_order_relaxed);
  // Done when nothing is queued and the last segment's time has passed on the machine.
  if (queue_.empty() && print_now_s > executed_end_s_ && planner_queued_.load() == 0) {
    steps_.flush();
    anchored = false;
  }
  telemetry_.anchored.store(anchored, std::memory_order_relaxed);
}

}  // namespace feedloop::engine
