#include "engine/step_pipeline.hpp"

#include <cmath>  // std::ceil

namespace feedloop::engine {

StepPipeline::StepPipeline(const StepPipelineParams& params, stepgen::BatchSink* sink)
    : params_(params) {
  const stepgen::TickMap map{0.0, params.mcu_clock_hz};
  host_maps_.fill(map);
  for (int j = 0; j < kJoints; ++j) {
    auto jt = std::make_unique<Joint>();
    jt->batcher.configure(static_cast<uint8_t>(j), params.max_batch_bytes, sink);
    stepgen::StepCompressorParams cp;
    cp.max_error_ticks = params.max_step_error_us * 1e-6 * params.mcu_clock_hz;
    if (!owns(j)) cp.max_run_count = 1;  // never fed: no point buffer (1.5 MB per joint)
    jt->run_tap.next = params.encode ? static_cast<stepgen::RunSink*>(&jt->batcher) : &null_runs_;
    jt->run_tap.observer = owns(j) ? params.observer : nullptr;
    jt->run_tap.joint = j;
    jt->compressor.configure(cp, &jt->run_tap);
    jt->compressor.reset(0, 0.0);
    jt->tap.next =
        params.compress ? static_cast<stepgen::StepSink*>(&jt->compressor) : &null_steps_;
    jt->gen.configure(params.steps_per_mm[static_cast<size_t>(j)], map, &jt->tap);
    joints_[static_cast<size_t>(j)] = std::move(jt);
  }
}

void StepPipeline::on_joint_segment(int joint, const JointSegment& segment) {
  if (!owns(joint)) return;
  if (params_.observer != nullptr) params_.observer->on_segment(joint, segment);
  joints_[static_cast<size_t>(joint)]->gen.add_segment(segment);
}

void StepPipeline::set_position_mm(int joint, double pos_mm) {
  Joint& j = *joints_[static_cast<size_t>(joint)];
  j.gen.set_position_mm(pos_mm);
  if (params_.observer != nullptr && owns(joint))
    params_.observer->on_origin(joint, j.compressor.last_emitted_clock(), j.gen.position_steps());
}

stepgen::TickMap StepPipeline::print_map(int joint) const {
  if (print_maps_direct_) return print_maps_[static_cast<size_t>(joint)];
  const stepgen::TickMap& h = host_maps_[static_cast<size_t>(joint)];
  return {h.offset_ticks + h.ticks_per_s * offset_s_, h.ticks_per_s};
}

void StepPipeline::apply_maps() {
  for (int j = 0; j < kJoints; ++j) joints_[static_cast<size_t>(j)]->gen.set_tick_map(print_map(j));
}

void StepPipeline::set_time_offset_s(double offset_s) {
  offset_s_ = offset_s;
  print_maps_direct_ = false;  // the host maps, anchored anew
  apply_maps();
  if (params_.observer != nullptr) params_.observer->on_time_offset(offset_s);
}

void StepPipeline::set_clock_maps(const std::array<stepgen::TickMap, kJoints>& host_to_ticks) {
  host_maps_ = host_to_ticks;
  print_maps_direct_ = false;
  apply_maps();
  if (params_.observer != nullptr) params_.observer->on_clock_maps(host_to_ticks);
}

void StepPipeline::set_print_maps(const std::array<stepgen::TickMap, kJoints>& print_to_ticks) {
  print_maps_ = print_to_ticks;
  print_maps_direct_ = true;
  // The host maps they amount to, for set_time_offset_s() and the observer.
  for (size_t j = 0; j < host_maps_.size(); ++j)
    host_maps_[j] = {print_to_ticks[j].offset_ticks - print_to_ticks[j].ticks_per_s * offset_s_,
                     print_to_ticks[j].ticks_per_s};
  apply_maps();
  if (params_.observer != nullptr) params_.observer->on_clock_maps(host_maps_);
}

void StepPipeline::flush_due(double deadline_s) {
  for (int jn = 0; jn < kJoints; ++jn) {
    Joint* j = joints_[static_cast<size_t>(jn)].get();
    const auto deadline_clock = static_cast<int64_t>(std::ceil(print_map(jn).ticks(deadline_s)));
    j->gen.flush();
    j->compressor.flush_if_due(deadline_clock);
    j->batcher.flush_if_due(deadline_clock);
  }
}

void StepPipeline::flush() {
  for (auto& j : joints_) {
    j->gen.flush();
    j->compressor.flush();
    j->batcher.flush();
  }
}

JointStepStats StepPipeline::stats(int joint) const {
  const Joint& j = *joints_[static_cast<size_t>(joint)];
  JointStepStats s;
  s.steps = j.gen.steps_emitted();
  s.runs = j.compressor.stats().runs;
  s.check_failures = j.compressor.stats().check_failures;
  s.compression = j.compressor.stats();
  s.batches = j.batcher.batches_total();
  s.body_bytes = j.batcher.body_bytes_total();
  if (j.tap.min_interval_ticks < 1e299 && j.tap.min_interval_ticks > 0)
    s.max_step_rate_hz = params_.mcu_clock_hz / j.tap.min_interval_ticks;
  return s;
}

}  // namespace feedloop::engine
