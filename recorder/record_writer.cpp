// RecordWriter: copies records into its ring (real-time safe; see record_writer.hpp).
#include "recorder/record_writer.hpp"

#include <algorithm>  // std::min
#include <chrono>
#include <thread>

namespace feedloop::recorder {

RecordWriter::RecordWriter(size_t ring_bytes, size_t max_text_bytes, int joints,
                           const std::atomic<bool>* enabled, const WaitForRoom* wait)
    : ring_(ring_bytes), joints_(std::min(joints, kMaxJoints)), enabled_(enabled), wait_(wait) {
  max_text_ = std::min(max_text_bytes, ring_.max_payload() - sizeof(GcodeLineHead) - 8);
}

void RecordWriter::push_full(RecordType t, const void* a, size_t na, const void* b, size_t nb) {
  // Virtual time only (WaitForRoom): wake the consumer and wait until it made room. The wait ends
  // when the mode is switched off (the recorder thread stops), so it cannot outlive its consumer.
  if (wait_ != nullptr && na + nb <= ring_.max_payload()) {
    while (wait_->on.load(std::memory_order_acquire)) {
      if (wait_->wake_consumer) wait_->wake_consumer(wait_->ctx);
      std::this_thread::sleep_for(std::chrono::microseconds(100));
      if (ring_.try_push(static_cast<uint8_t>(t), a, na, b, nb)) {
        waits_.fetch_add(1, std::memory_order_relaxed);
        return;
      }
    }
  }
  dropped_.fetch_add(1, std::memory_order_relaxed);
}

void RecordWriter::gcode_line(int64_t time_ns, GcodeSource source, std::string_view text) {
  if (!on()) return;
  GcodeLineHead h;
  h.time_ns = time_ns;
  h.original_length = static_cast<uint32_t>(std::min<size_t>(text.size(), UINT32_MAX));
  h.source = static_cast<uint8_t>(source);
  const size_t n = std::min(text.size(), max_text_);
  push(RecordType::gcode_line, &h, sizeof h, text.data(), n);
}

void RecordWriter::move(const planner::PlannedMove& m) {
  if (!on()) return;
  MoveRecord r;
  r.index = m.index;
  r.line = m.line;
  r.start_time_s = m.start_time_s;
  r.duration_s = m.duration_s;
  r.start_mm = m.start_mm;
  r.end_mm = m.end_mm;
  r.v_entry_mm_s = m.v_entry_mm_s;
  r.v_cruise_mm_s = m.v_cruise_mm_s;
  r.v_exit_mm_s = m.v_exit_mm_s;
  r.accel_mm_s2 = m.accel_mm_s2;
  push(RecordType::move, &r, sizeof r);
}

void RecordWriter::move(const MoveRecord& m) {
  if (!on()) return;
  push(RecordType::move, &m, sizeof m);
}

void RecordWriter::segment(int joint, const JointSegment& s) {
  if (!on() || !joint_ok(joint)) return;
  const SegmentRecord r{joint, s};
  push(RecordType::segment, &r, sizeof r);
}

void RecordWriter::step_run(int joint, int64_t start_clock, const stepgen::StepRun& run) {
  if (!on() || !joint_ok(joint)) return;
  const StepRunRecord r{joint, start_clock, run};
  push(RecordType::step_run, &r, sizeof r);
}

void RecordWriter::encoder_sample(int joint, int64_t clock, int64_t counts) {
  if (!on() || !joint_ok(joint)) return;
  const EncoderRecord r{joint, clock, counts};
  push(RecordType::encoder, &r, sizeof r);
}

void RecordWriter::origin(int joint, int64_t clock, int64_t position_steps) {
  if (!on() || !joint_ok(joint)) return;
  const OriginRecord r{joint, clock, position_steps};
  push(RecordType::origin, &r, sizeof r);
}

void RecordWriter::loop_report(const LoopReportRecord& r) {
  if (!on() || !joint_ok(r.joint)) return;
  push(RecordType::loop_report, &r, sizeof r);
}

void RecordWriter::event(EventKind kind, int64_t time_ns, int joint, double value, std::string_view text) {
  if (!on()) return;
  EventHead h;
  h.time_ns = time_ns;
  h.value = value;
  h.joint = (joint >= 0 && joint < joints_) ? joint : -1;
  h.kind = static_cast<uint8_t>(kind);
  push(RecordType::event, &h, sizeof h, text.data(), std::min<size_t>(text.size(), 256));
}

}  // namespace feedloop::recorder
