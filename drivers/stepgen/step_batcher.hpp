// Packs the runs of one axis into QUEUE_STEPS batch bodies (run_codec.hpp) of at most
// max_body_bytes, handing each full batch to a BatchSink. Fixed buffer: no allocation.
#pragma once

#include <cstddef>
#include <cstdint>

#include "drivers/stepgen/run_codec.hpp"
#include "drivers/stepgen/step_run.hpp"

namespace feedloop::stepgen {

struct StepBatch {
  uint8_t axis = 0;
  const uint8_t* body = nullptr;  // run_codec body (valid during the callback only)
  size_t body_bytes = 0;
  uint32_t runs = 0;
  uint64_t steps = 0;
  int64_t first_clock = 0;  // reference P of the first run
  int64_t last_clock = 0;   // clock of the last step
};

class BatchSink {
 public:
  virtual ~BatchSink() = default;
  virtual void on_batch(const StepBatch& batch) = 0;
};

class StepBatcher final : public RunSink {
 public:
  static constexpr size_t kMaxBody = 1024;
  void configure(uint8_t axis, size_t max_body_bytes, BatchSink* sink) {
    axis_ = axis;
    cap_ = max_body_bytes < 16 ? 16 : (max_body_bytes > kMaxBody ? kMaxBody : max_body_bytes);
    sink_ = sink;
    open_ = false;
  }
  void on_run(int64_t start_clock, const StepRun& run) override {
    if (!open_) open_batch(start_clock);
    if (!enc_.append(run)) {
      flush();
      open_batch(start_clock);
      enc_.append(run);
    }
    if (enc_.runs() == 1) first_step_clock_ = start_clock + run.interval_ticks;
    last_clock_ = run_end_clock(start_clock, run);
  }
  // Sends the open batch, if any.
  void flush() {
    if (!open_) return;
    open_ = false;
    if (enc_.runs() == 0) return;
    StepBatch b{axis_, buf_, enc_.size(), enc_.runs(), enc_.steps(), first_clock_, last_clock_};
    bytes_total_ += enc_.size();
    ++batches_total_;
    if (sink_ != nullptr) sink_->on_batch(b);
  }
  // Sends the open batch if its first step is at or before deadline_clock.
  void flush_if_due(int64_t deadline_clock) {
    if (open_ && enc_.runs() > 0 && first_step_clock_ <= deadline_clock) flush();
  }
  uint64_t body_bytes_total() const { return bytes_total_; }
  uint64_t batches_total() const { return batches_total_; }

 private:
  void open_batch(int64_t start_clock) {
    enc_.begin(buf_, cap_, static_cast<uint64_t>(start_clock));
    first_clock_ = start_clock;
    open_ = true;
  }
  uint8_t axis_ = 0;
  size_t cap_ = 200;
  BatchSink* sink_ = nullptr;
  bool open_ = false;
  RunEncoder enc_;
  uint8_t buf_[kMaxBody] = {};
  int64_t first_clock_ = 0, last_clock_ = 0, first_step_clock_ = 0;
  uint64_t bytes_total_ = 0, batches_total_ = 0;
};

}  // namespace feedloop::stepgen
