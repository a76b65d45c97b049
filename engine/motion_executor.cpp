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
      queue_(options.joint_queue_capacity),
      batches_(std::move(batches)),
      steps_(sp, batches_.get()) {
  interp_ = std::make_unique<planner::Interpreter>(pcfg_, *kin_, planner_);
}

Status MotionExecutor::execute(const gcode::Command& cmd, const std::atomic<bool>& cancel) {
  cancel_ = &cancel;
  wait_until_s_ = -1.0;
  last_command_ = std::chrono::steady_clock::now();
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
  const auto quiet = std::chrono::steady_clock::now() - last_command_;
  if (quiet > std::chrono::duration<double>(options_.input_pause_flush_s)) planner_.flush();
  planner_queued_.store(planner_.queued());
}

bool MotionExecutor::motion_pending() const {
  return planner_queued_.load() > 0 || pushed_.load() != popped_.load() ||
         telemetry_.anchored.load(std::memory_order_relaxed);
}

void MotionExecutor::on_move(const planner::PlannedMove& m) { emitter_.emit(m, *this); }

void MotionExecutor::on_event(const planner::PlannerEvent& e) {
  if (e.kind == planner::EventKind::moves_done) wait_until_s_ = e.time_s;
}

void MotionExecutor::on_joint_segment(int joint, const JointSegment& segment) {
  const JointItem item{joint, segment};
  while (!queue_.try_push(item)) {  // backpressure: the servo side is `queue` seconds behind
    if (cancel_ != nullptr && cancel_->load()) return;
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  pushed_.fetch_add(1, std::memory_order_release);
  double end = planned_end_s_.load(std::memory_order_relaxed);
  if (segment.end_s() > end) planned_end_s_.store(segment.end_s(), std::memory_order_relaxed);
}

void MotionExecutor::wait_print_time(double t_s, const std::atomic<bool>& cancel) {
  planner_.flush();
  planner_queued_.store(planner_.queued());
  while (!cancel.load()) {
    if (!motion_pending()) return;
    if (telemetry_.anchored.load() && telemetry_.print_time_s.load() >= t_s) return;
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
}

void MotionExecutor::servo_cycle(int64_t now_ns, bool cancel) {
  const double now_s = static_cast<double>(now_ns) * 1e-9;
  if (cancel) {  // drop everything not yet turned into steps
    JointItem drop;
    while (queue_.try_pop(drop)) popped_.fetch_add(1, std::memory_order_release);
    if (telemetry_.anchored.load()) steps_.flush();
    telemetry_.anchored.store(false);
    return;
  }
  const double horizon_s = now_s + options_.lead_s;
  bool anchored = telemetry_.anchored.load(std::memory_order_relaxed);
  while (const JointItem* front = queue_.front()) {
    if (!anchored) {  // motion starts from rest: print time t0 runs lead_s from now
      offset_s_ = horizon_s - front->segment.t0_s;
      steps_.set_time_offset_s(offset_s_);
      anchored = true;
      telemetry_.anchors.fetch_add(1, std::memory_order_relaxed);
    }
    if (front->segment.t0_s + offset_s_ > horizon_s) break;
    steps_.on_joint_segment(front->joint, front->segment);
    executed_end_s_ = std::max(executed_end_s_, front->segment.end_s());
    JointItem done;
    queue_.try_pop(done);
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
