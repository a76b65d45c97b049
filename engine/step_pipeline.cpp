#include "engine/step_pipeline.hpp"

#include <cmath>  // std::ceil

namespace feedloop::engine {

StepPipeline::StepPipeline(const StepPipelineParams& params, stepgen::BatchSink* sink)
    : params_(params) {
  const stepgen::TickMap map{0.0, params.mcu_clock_hz};
  for (int j = 0; j < kJoints; ++j) {
    auto jt = std::make_unique<Joint>();
    jt->batcher.configure(static_cast<uint8_t>(j), params.max_batch_bytes, sink);
    stepgen::StepCompressorParams cp;
    cp.max_error_ticks = params.max_step_error_us * 1e-6 * params.mcu_clock_hz;
    jt->compressor.configure(cp, &jt->batcher);
    jt->compressor.reset(0, 0.0);
    jt->tap.next = &jt->compressor;
    jt->gen.configure(params.steps_per_mm[static_cast<size_t>(j)], map, &jt->tap);
    joints_[static_cast<size_t>(j)] = std::move(jt);
  }
}

void StepPipeline::on_joint_segment(int joint, const JointSegment& segment) {
  joints_[static_cast<size_t>(joint)]->gen.add_segment(segment);
}

void StepPipeline::set_time_offset_s(double offset_s) {
  offset_s_ = offset_s;
  for (auto& j : joints_) j->gen.set_tick_map({offset_s * params_.mcu_clock_hz, params_.mcu_clock_hz});
}

void StepPipeline::flush_due(double deadline_s) {
  const auto deadline_clock =
      static_cast<int64_t>(std::ceil((deadline_s + offset_s_) * params_.mcu_clock_hz));
  for (auto& j : joints_) {
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
  s.batches = j.batcher.batches_total();
  s.body_bytes = j.batcher.body_bytes_total();
  if (j.tap.min_interval_ticks < 1e299 && j.tap.min_interval_ticks > 0)
    s.max_step_rate_hz = params_.mcu_clock_hz / j.tap.min_interval_ticks;
  return s;
}

}  // namespace feedloop::engine
