// One joint's whole step path in one object, for the engine and batch mode: exact step times
// (StepGenerator) -> runs (StepCompressor) -> QUEUE_STEPS batch bodies (StepBatcher) -> a
// BatchSink (e.g. McuSession::queue_steps, or a byte counter in batch mode).
//
//   AxisStepper x;  x.configure(0, 80.0, {}, tick_map, &sink);
//   per segment:    x.add_segment(seg);
//   per servo tick: x.flush_due(clock_now + lead_ticks);   // closes runs/batches about to be due
//   at the end:     x.finish();
//
// RT-safe after configure() (no allocation). Owner: the thread that feeds the segments.
#pragma once

#include <cstdint>

#include "core/joint_segment.hpp"
#include "drivers/stepgen/step_batcher.hpp"
#include "drivers/stepgen/step_compressor.hpp"
#include "drivers/stepgen/step_generator.hpp"

namespace feedloop::stepgen {

struct AxisStepperParams {
  StepCompressorParams compression;  // max_error_ticks: 5 us at the MCU clock
  size_t max_batch_body_bytes = 200;  // fits a frame with headers (protocol::kMaxPayload = 240)
};

class AxisStepper {
 public:
  void configure(uint8_t axis, double steps_per_mm, const AxisStepperParams& p, TickMap map, BatchSink* sink,
                 double start_pos_mm = 0.0) {
    batcher_.configure(axis, p.max_batch_body_bytes, sink);
    compressor_.configure(p.compression, &batcher_);
    generator_.configure(steps_per_mm, map, &compressor_);
    generator_.set_position_mm(start_pos_mm);
    map_ = map;
  }
  // Starts the step stream at print time t_s (the reference of the first run).
  void start_at(double t_s) {
    const double ticks = map_.ticks(t_s);
    compressor_.reset(static_cast<int64_t>(ticks), ticks);
  }
  void set_tick_map(TickMap map) {
    map_ = map;
    generator_.set_tick_map(map);
  }
  void add_segment(const JointSegment& s) { generator_.add_segment(s); }
  // Everything whose first step is at or before deadline_clock leaves now.
  void flush_due(int64_t deadline_clock) {
    generator_.flush();
    compressor_.flush_if_due(deadline_clock);
    batcher_.flush_if_due(deadline_clock);
  }
  void finish() {
    generator_.flush();
    compressor_.flush();
    batcher_.flush();
  }
  int64_t position_steps() const { return generator_.position_steps(); }
  uint64_t steps() const { return generator_.steps_emitted(); }
  uint64_t body_bytes() const { return batcher_.body_bytes_total(); }
  uint64_t batches() const { return batcher_.batches_total(); }
  const StepCompressorStats& compression_stats() const { return compressor_.stats(); }

 private:
  StepGenerator generator_;
  StepCompressor compressor_;
  StepBatcher batcher_;
  TickMap map_;
};

}  // namespace feedloop::stepgen
