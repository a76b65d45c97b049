// The real-time side of the flight recorder: one RecordWriter per producer thread (I/O, planner,
// servo), each with its own lock-free SPSC ring. Every call copies a small POD into the ring and
// returns: no allocation, no lock, no system call. When the ring is full the record is dropped
// and dropped() increments (the recorder thread writes a DropRecord into the log). A writer must be
// used by one thread at a time.
//
// Virtual time is the exception (WaitForRoom): there the servo thread runs at CPU speed and can
// fill its ring faster than a descheduled recorder thread empties it, and a dropped step run
// shifts a recording's commanded position for good. So in virtual time a push that finds its ring
// full wakes the recorder thread and waits for room instead (nothing is lost; no deadline exists
// to miss). Real time never waits.
#pragma once

#include <atomic>
#include <cstdint>
#include <string_view>

#include "core/joint_segment.hpp"
#include "drivers/stepgen/step_run.hpp"
#include "planner/move.hpp"
#include "recorder/byte_ring.hpp"
#include "recorder/records.hpp"

namespace feedloop::recorder {

// Ring payload heads of the variable-length records (the text follows).
struct GcodeLineHead {
  int64_t time_ns = 0;
  uint32_t original_length = 0;
  uint8_t source = 0;
};
struct EventHead {
  int64_t time_ns = 0;
  double value = 0.0;
  int32_t joint = -1;
  uint8_t kind = 0;
};

// Owned by the Recorder, shared by its writers: whether a full ring waits (virtual time), and how
// to wake the ring's consumer.
struct WaitForRoom {
  std::atomic<bool> on{false};
  void (*wake_consumer)(void* ctx) = nullptr;
  void* ctx = nullptr;
};

class RecordWriter {
 public:
  // `enabled` (owned by the Recorder) switches every call to a no-op when false; `wait` (may be
  // null) makes a full ring wait for room while wait->on.
  RecordWriter(size_t ring_bytes, size_t max_text_bytes, int joints,
               const std::atomic<bool>* enabled, const WaitForRoom* wait = nullptr);
  RecordWriter(const RecordWriter&) = delete;
  RecordWriter& operator=(const RecordWriter&) = delete;

  // I/O thread: a G-code line as received (without its newline). Lines longer than the text limit
  // are cut; the record keeps the original length.
  void gcode_line(int64_t time_ns, GcodeSource source, std::string_view text);
  // Planner thread: a final move.
  void move(const planner::PlannedMove& m);
  void move(const MoveRecord& m);
  // Planner or servo thread: joint motion handed to step generation.
  void segment(int joint, const JointSegment& s);
  // Servo thread: a compressed step run as sent (start_clock = the run's reference P).
  void step_run(int joint, int64_t start_clock, const stepgen::StepRun& r);
  // Servo thread: an encoder report.
  void encoder_sample(int joint, int64_t clock, int64_t counts);
  // From `clock` on the joint's step counter is `position_steps` (stream start, homing, G92).
  void origin(int joint, int64_t clock, int64_t position_steps);
  // Servo thread: a device loop's report (LOOP_REPORT).
  void loop_report(const LoopReportRecord& r);
  // Any thread that owns this writer: errors, lost steps, deadline misses, time anchors.
  void event(EventKind kind, int64_t time_ns, int joint, double value, std::string_view text = {});

  uint64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }
  uint64_t rejected() const { return rejected_.load(std::memory_order_relaxed); }  // bad joint index
  // Pushes that found the ring full and waited for room (WaitForRoom, virtual time).
  uint64_t waited() const { return waits_.load(std::memory_order_relaxed); }
  ByteRing& ring() { return ring_; }

 private:
  bool on() const { return enabled_->load(std::memory_order_relaxed); }
  bool joint_ok(int joint) {
    if (joint >= 0 && joint < joints_) return true;
    rejected_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  void push(RecordType t, const void* a, size_t na, const void* b = nullptr, size_t nb = 0) {
    if (!ring_.try_push(static_cast<uint8_t>(t), a, na, b, nb)) push_full(t, a, na, b, nb);
  }
  // The ring was full: wait for room (virtual time) or count a drop.
  void push_full(RecordType t, const void* a, size_t na, const void* b, size_t nb);

  ByteRing ring_;
  size_t max_text_;
  int joints_;
  const std::atomic<bool>* enabled_;
  const WaitForRoom* wait_;
  std::atomic<uint64_t> dropped_{0};
  std::atomic<uint64_t> rejected_{0};
  std::atomic<uint64_t> waits_{0};
};

}  // namespace feedloop::recorder
