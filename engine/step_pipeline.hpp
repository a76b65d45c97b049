// Joint motion -> exact step times -> compressed runs -> batches, for every joint:
//
//   JointSegment --StepGenerator--> step ticks --StepTap--> StepCompressor --RunTap--> StepBatcher --> BatchSink
//
// An optional StepObserver (the flight recorder, recorder/engine_recording.hpp) sees every
// compressed run exactly as it goes to the batcher, every position reset and every change of the
// time base, so that the commanded step stream can be recorded bit for bit.
//
// The same object serves batch mode (BatchSink counts bytes; an ideal plant) and the daemon's
// servo thread (BatchSink = the MCU sessions). RT-safe after construction: no allocation.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <memory>

#include "drivers/stepgen/step_batcher.hpp"
#include "drivers/stepgen/step_compressor.hpp"
#include "drivers/stepgen/step_generator.hpp"
#include "engine/config_mapping.hpp"
#include "planner/joint_output.hpp"

namespace feedloop::engine {

// Observes what the pipeline commands. Called on the thread that drives the pipeline (the servo
// thread in the daemon): implementations must be RT-safe (no allocation, no lock, no I/O).
class StepObserver {
 public:
  virtual ~StepObserver() = default;
  // Every compressed run of an owned joint, as handed to the batcher (start_clock: the run's
  // reference P, the clock of the step before its first).
  virtual void on_step_run(int joint, int64_t start_clock, const stepgen::StepRun& run) = 0;
  // The joint's step counter was set to `position_steps` without steps; the joint's last step
  // so far is at `clock` (0: none yet).
  virtual void on_origin(int joint, int64_t clock, int64_t position_steps) = 0;
  // Print time re-anchored: host time = print time + offset_s.
  virtual void on_time_offset(double /*offset_s*/) {}
  // The host time -> MCU tick maps in use from now on (every servo cycle with a backend).
  virtual void on_clock_maps(const std::array<stepgen::TickMap, kJoints>& /*host_to_ticks*/) {}
  // A joint segment of an owned joint, before step generation.
  virtual void on_segment(int /*joint*/, const JointSegment& /*segment*/) {}
};

struct StepPipelineParams {
  std::array<double, kJoints> steps_per_mm{};
  double mcu_clock_hz = 72e6;
  double max_step_error_us = 5.0;  // bound on |compressed - exact| step time
  size_t max_batch_bytes = 200;    // body of one QUEUE_STEPS message
  // Joints this pipeline steps (bit j = joint j); segments of the others are ignored, so two
  // pipelines on two threads can share one joint-segment stream (batch mode).
  unsigned joint_mask = 0xFu;
  StepObserver* observer = nullptr;  // optional; must outlive the pipeline
  // Bench/batch's time per stage only: stop after the exact step times (compress = false) or
  // after compression (encode = false: no batches).
  bool compress = true;
  bool encode = true;
};

struct JointStepStats {
  uint64_t steps = 0;
  uint64_t runs = 0;
  uint64_t batches = 0;
  uint64_t body_bytes = 0;
  double max_step_rate_hz = 0.0;  // 1 / shortest interval between two steps
  uint64_t check_failures = 0;    // runs that failed the re-expansion check (expected 0)
  stepgen::StepCompressorStats compression{};  // the compressor's cost counters
};

class StepPipeline final : public planner::JointSink {
 public:
  StepPipeline(const StepPipelineParams& params, stepgen::BatchSink* sink);

  void on_joint_segment(int joint, const JointSegment& segment) override;
  bool owns(int joint) const { return (params_.joint_mask >> joint) & 1u; }
  // Sets a joint's position without steps (start of a stream).
  void set_position_mm(int joint, double pos_mm);
  // The joint's next stream continues after MCU clock last_step_clock: steps someone else queued
  // on its MCU (a homing, drivers/host/homing.hpp) end there, and the MCU refuses a batch that
  // starts before the end of what it holds. Call only when no steps are pending.
  void restart_stream(int joint, int64_t last_step_clock);
  // Host time = print time + offset: re-anchors the print-time line on the host clock (the daemon
  // does this when motion starts from rest). Call only when no steps are pending.
  void set_time_offset_s(double offset_s);
  // Host time -> MCU ticks per joint (each joint's MCU clock as the clock sync estimates it,
  // drivers/clock_sync.hpp). Default: an ideal clock, ticks = mcu_clock_hz * host time. May be
  // refreshed between segments while steps are pending (small corrections as the estimate
  // improves); print time -> ticks is then offset_ticks + rate (print + offset_s).
  void set_clock_maps(const std::array<stepgen::TickMap, kJoints>& host_to_ticks);
  // Print time -> MCU ticks per joint, given directly (the device loop's clock frame,
  // engine/motion_executor.hpp): no detour through host time, whose large values cost the sum
  // its last thousandth of a tick, differently in every run. Until the next set_clock_maps().
  void set_print_maps(const std::array<stepgen::TickMap, kJoints>& print_to_ticks);
  // Closes runs and batches whose first step is due by `deadline_s` (print time).
  void flush_due(double deadline_s);
  // Emits everything pending (end of a stream).
  void flush();

  JointStepStats stats(int joint) const;
  int64_t position_steps(int joint) const { return joints_[static_cast<size_t>(joint)]->gen.position_steps(); }
  const StepPipelineParams& params() const { return params_; }

 private:
  // Watches the exact step times on their way to the compressor: the max step rate is the
  // shortest interval between two steps in the same direction (a reversal exactly at a step
  // threshold makes a step and its undo arbitrarily close; that is not a rate).
  struct StepTap final : stepgen::StepSink {
    stepgen::StepSink* next = nullptr;
    double last_ticks = -1e300;
    int8_t last_dir = 0;
    double min_interval_ticks = 1e300;
    void on_steps(const double* ticks, const int8_t* dirs, size_t n) override {
      if (n == 0) return;
      // Branch-free, in four independent minima (no chain through one running minimum or the
      // previous step): this loop was 4 % of batch mode's time.
      auto gap = [&](size_t i) { return dirs[i] == dirs[i - 1] ? ticks[i] - ticks[i - 1] : 1e300; };
      double m0 = dirs[0] == last_dir ? ticks[0] - last_ticks : 1e300, m1 = 1e300, m2 = 1e300,
             m3 = 1e300;
      size_t i = 1;
      for (; i + 4 <= n; i += 4) {
        m0 = std::min(m0, gap(i));
        m1 = std::min(m1, gap(i + 1));
        m2 = std::min(m2, gap(i + 2));
        m3 = std::min(m3, gap(i + 3));
      }
      for (; i < n; ++i) m0 = std::min(m0, gap(i));
      min_interval_ticks = std::min({min_interval_ticks, m0, m1, m2, m3});
      last_ticks = ticks[n - 1];
      last_dir = dirs[n - 1];
      next->on_steps(ticks, dirs, n);
    }
  };
  // Compressor -> observer -> batcher.
  struct RunTap final : stepgen::RunSink {
    stepgen::RunSink* next = nullptr;
    StepObserver* observer = nullptr;
    int joint = 0;
    void on_run(int64_t start_clock, const stepgen::StepRun& run) override {
      if (observer != nullptr) observer->on_step_run(joint, start_clock, run);
      next->on_run(start_clock, run);
    }
  };
  struct NullSteps final : stepgen::StepSink {
    void on_steps(const double*, const int8_t*, size_t) override {}
  };
  struct NullRuns final : stepgen::RunSink {
    void on_run(int64_t, const stepgen::StepRun&) override {}
  };
  struct Joint {
    stepgen::StepGenerator gen;
    StepTap tap;
    stepgen::StepCompressor compressor;
    RunTap run_tap;
    stepgen::StepBatcher batcher;
  };

  stepgen::TickMap print_map(int joint) const;
  void apply_maps();

  StepPipelineParams params_;
  NullSteps null_steps_;
  NullRuns null_runs_;
  double offset_s_ = 0.0;
  std::array<stepgen::TickMap, kJoints> host_maps_{};
  std::array<stepgen::TickMap, kJoints> print_maps_{};
  bool print_maps_direct_ = false;  // set_print_maps() in force
  std::array<std::unique_ptr<Joint>, kJoints> joints_;
};

}  // namespace feedloop::engine
