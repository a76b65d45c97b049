#include "recorder/engine_recording.hpp"

#include <cmath>

namespace feedloop::recorder {

EngineRecording::EngineRecording(Recorder& recorder, const Clock& clock, EngineRecordingOptions options)
    : rec_(recorder), clock_(clock), options_(options) {
  const std::vector<JointInfo>& joints = recorder.header_template().joints;
  joints_ = static_cast<int>(std::min<size_t>(joints.size(), engine::kJoints));
  for (int j = 0; j < engine::kJoints; ++j) {
    const auto js = static_cast<size_t>(j);
    // Until the engine reports its clock maps (no MCUs): an ideal clock, as StepPipeline's.
    maps_[js] = stepgen::TickMap{0.0, j < joints_ ? static_cast<double>(joints[js].clock_hz) : 0.0};
    encoder_mm_per_count_[js] = j < joints_ ? joints[js].encoder_resolution_mm : 0.0;
  }
}

void EngineRecording::on_step_run(int joint, int64_t start_clock, const stepgen::StepRun& run) {
  rec_.writer(Stream::servo).step_run(joint, start_clock, run);
}

void EngineRecording::on_origin(int joint, int64_t clock, int64_t position_steps) {
  rec_.writer(Stream::servo).origin(joint, clock, position_steps);
}

void EngineRecording::on_time_offset(double offset_s) {
  ++anchors_;
  rec_.writer(Stream::servo).event(EventKind::time_anchor, clock_.now_ns(), -1, offset_s);
}

void EngineRecording::on_clock_maps(const std::array<stepgen::TickMap, engine::kJoints>& host_to_ticks) {
  maps_ = host_to_ticks;
}

void EngineRecording::on_segment(int joint, const JointSegment& segment) {
  if (options_.record_segments) rec_.writer(Stream::servo).segment(joint, segment);
}

void EngineRecording::on_planned_move(const planner::PlannedMove& m) { rec_.writer(Stream::planner).move(m); }

void EngineRecording::on_servo_sample(const engine::ServoSample& s) {
  if (!options_.record_encoders) return;
  for (int j = 0; j < joints_; ++j) {
    const auto js = static_cast<size_t>(j);
    if (mcu_samples_[js]) continue;
    const double mm = s.encoder_mm[js];
    const double res = encoder_mm_per_count_[js];
    if (!(res > 0.0) || !std::isfinite(mm)) continue;
    const auto counts = static_cast<int64_t>(std::llround(mm / res));
    if (have_counts_[js] && counts == last_counts_[js]) continue;
    have_counts_[js] = true;
    last_counts_[js] = counts;
    // The joint's MCU clock at the cycle that saw the reading (the steps' time line).
    const auto clock = static_cast<int64_t>(std::llround(maps_[js].ticks(s.host_time_s)));
    rec_.writer(Stream::servo).encoder_sample(j, clock, counts);
    ++encoder_samples_;
  }
}

// Every sample at the MCU's clock of its taking: the trace export interpolates between samples
// one servo period apart (a cycle's latest reading was up to a report, 10 periods, old, and
// stamped with the cycle's time: the exported carriage lagged its steps by 5-8 ms).
void EngineRecording::on_encoder_sample(const engine::EncoderReading& r) {
  if (!options_.record_encoders || r.joint < 0 || r.joint >= joints_) return;
  const auto js = static_cast<size_t>(r.joint);
  const double res = encoder_mm_per_count_[js];
  if (!(res > 0.0) || !std::isfinite(r.mm)) return;
  mcu_samples_[js] = true;
  const auto counts = static_cast<int64_t>(std::llround(r.mm / res));
  have_counts_[js] = true;
  last_counts_[js] = counts;
  rec_.writer(Stream::servo).encoder_sample(r.joint, r.clock, counts);
  ++encoder_samples_;
}

void EngineRecording::on_servo_event(const engine::ServoEvent& e) {
  const EventKind kind = e.kind == engine::ServoEventKind::kLostSteps      ? EventKind::lost_steps
                         : e.kind == engine::ServoEventKind::kDeadlineMiss ? EventKind::deadline_miss
                                                                           : EventKind::error;
  rec_.writer(Stream::servo).event(kind, clock_.now_ns(), e.joint, e.size_mm, engine::to_string(e.kind));
}

}  // namespace feedloop::recorder

namespace feedloop::recorder {

void EngineRecording::on_device_loop_report(const engine::DeviceLoopReport& r) {
  if (!options_.record_loop_reports || r.joint < 0 || r.joint >= joints_) return;
  LoopReportRecord l;
  l.joint = r.joint;
  l.clock = r.clock;
  l.state = r.state;
  l.e_nm = std::llround(r.e_mm * 1e6);
  l.y_nm = std::llround(r.y_mm * 1e6);
  l.correction_nm = std::llround(r.correction_mm * 1e6);
  l.tick_cost = r.tick_cost;
  l.ticks = r.ticks;
  l.deadline_misses = r.deadline_misses;
  l.encoder_rejects = r.encoder_rejects;
  l.slips = r.slips;
  rec_.writer(Stream::servo).loop_report(l);
  ++loop_reports_;
}

}  // namespace feedloop::recorder
