// The desired carriage trajectory r(t) of one axis on the device: a fixed ring of knots (MCU
// clock, position nm) sent by the host in QUEUE_TARGET; r is the straight line between
// consecutive knots (the host's compressor keeps it within its error bound of the true r,
// drivers/protocol/target_codec.hpp). Before the first knot r holds the first knot's position;
// at or after the last knot (the horizon) it holds the last one, and the loop's watchdog stops
// the axis before that happens (axis_loop.hpp).
// Owner: the device's loop (one thread / interrupt level). No heap, no exceptions.
#pragma once

#include <cstdint>

namespace feedloop::device {

struct TargetKnot {
  int64_t clock = 0;   // MCU ticks
  int64_t pos_nm = 0;  // carriage position
};

struct TargetSample {
  int64_t pos_nm = 0;
  float velocity_nm_s = 0.0f;  // slope of the current piece (0 outside the queue)
  bool valid = false;          // false: the queue is empty
  bool beyond_horizon = false; // clock >= the last knot's clock
};

class TargetQueue {
 public:
  static constexpr int kCapacity = 512;

  void reset();
  // Appends a knot; false (nothing changes) when the queue is full or the clock does not
  // increase strictly over the last knot.
  bool push(const TargetKnot& k);
  // r at `clock`: drops the knots that lie wholly in the past (a piece ends at its second knot),
  // so calls must come with non-decreasing clocks. clock_hz converts the slope to nm/s.
  TargetSample at(int64_t clock, float clock_hz);

  int size() const { return count_; }
  int free() const { return kCapacity - count_; }
  bool empty() const { return count_ == 0; }
  // Clock of the last knot (meaningful when !empty()).
  int64_t horizon_clock() const { return last_.clock; }
  const TargetKnot& last() const { return last_; }

 private:
  void cache_piece();
  TargetKnot knots_[kCapacity];
  int head_ = 0, count_ = 0;
  TargetKnot last_;
  // The piece between knots_[head_] and the next, prepared once per piece.
  bool piece_valid_ = false;
  float inv_duration_ = 0.0f;   // 1 / (t1 - t0) in 1/ticks
  float delta_nm_ = 0.0f;       // p1 - p0
};

}  // namespace feedloop::device
