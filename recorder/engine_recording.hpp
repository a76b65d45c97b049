// The flight recorder wired into the engine: one object that the motion executor and its step
// pipeline report to, turning what they do into records on the recorder's rings.
//
//   StepPipeline --StepObserver--> step runs, origins, time anchors, clock maps (servo thread)
//   MotionExecutor --TelemetryTap--> planned moves (planner thread), encoder samples and events
//                                    (servo thread)
//
// Every call is RT-safe (RecordWriter calls: a copy into a lock-free ring; no allocation, no lock,
// no system call). Time stamps of events come from the engine's Clock. docs/recorder.md.
#pragma once

#include <array>
#include <cstdint>

#include "core/clock.hpp"
#include "engine/step_pipeline.hpp"
#include "engine/telemetry_tap.hpp"
#include "recorder/recorder.hpp"

namespace feedloop::recorder {

struct EngineRecordingOptions {
  // Joint segments (the exact joint targets handed to step generation). They cost about
  // 15-50 B each, one per joint and servo period while moving; the step runs are the bit-exact
  // record either way.
  bool record_segments = true;
  // Encoder samples: one per servo period and joint with an encoder, only when the reading
  // changed (a carriage at rest costs nothing).
  bool record_encoders = true;
  // The device loops' reports (100 Hz per joint with a device loop, about 10 B each).
  bool record_loop_reports = true;
};

class EngineRecording final : public engine::StepObserver, public engine::TelemetryTap {
 public:
  EngineRecording(Recorder& recorder, const Clock& clock, EngineRecordingOptions options = {});

  // engine::StepObserver (servo thread)
  void on_step_run(int joint, int64_t start_clock, const stepgen::StepRun& run) override;
  void on_origin(int joint, int64_t clock, int64_t position_steps) override;
  void on_time_offset(double offset_s) override;
  void on_clock_maps(const std::array<stepgen::TickMap, engine::kJoints>& host_to_ticks) override;
  void on_segment(int joint, const JointSegment& segment) override;

  // engine::TelemetryTap
  void on_planned_move(const planner::PlannedMove& m) override;  // planner thread
  void on_servo_sample(const engine::ServoSample& s) override;   // servo thread
  void on_servo_event(const engine::ServoEvent& e) override;     // servo thread
  void on_device_loop_report(const engine::DeviceLoopReport& r) override;  // servo thread
  void on_encoder_sample(const engine::EncoderReading& r) override;        // servo thread

  uint64_t encoder_samples() const { return encoder_samples_; }
  uint64_t anchors() const { return anchors_; }
  uint64_t loop_reports() const { return loop_reports_; }

 private:
  Recorder& rec_;
  const Clock& clock_;
  EngineRecordingOptions options_;
  int joints_ = 0;
  std::array<double, engine::kJoints> encoder_mm_per_count_{};
  // servo thread
  std::array<stepgen::TickMap, engine::kJoints> maps_{};
  std::array<int64_t, engine::kJoints> last_counts_{};
  std::array<bool, engine::kJoints> have_counts_{};
  // The joint's samples come from the MCUs with their own clocks (on_encoder_sample): the
  // cycles' latest reading is not recorded for it.
  std::array<bool, engine::kJoints> mcu_samples_{};
  uint64_t encoder_samples_ = 0;
  uint64_t anchors_ = 0;
  uint64_t loop_reports_ = 0;
};

}  // namespace feedloop::recorder
