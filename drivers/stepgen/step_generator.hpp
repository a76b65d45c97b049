// Exact step times of one joint from its stream of JointSegments (core/joint_segment.hpp).
//
// Step convention (documented in docs/protocol.md, "Step generation"): the motor's step count is
// n = round(s) where s(t) = steps_per_mm * pos_mm(t). A step happens when s(t) crosses a
// half-integer threshold n + 1/2 (upwards: n -> n+1, direction +1) or n - 1/2 (downwards:
// n -> n-1, direction -1). There is no hysteresis, so a reversal that re-crosses the same
// threshold makes a step back.
//
// Per segment, s(tau) = a + b tau + c tau^2 + e tau^3 is split at the roots of s'(tau) into
// monotonic pieces. On a quadratic piece each threshold x is solved in closed form with the
// cancellation-free root  tau = 2 D / (b + d sqrt(b^2 + 4 c D)),  D = x - a,  d = direction.
// On a cubic piece a safeguarded Newton iteration (bisection fallback inside the bracket) is used.
//
// Step times are converted to MCU ticks with a linear TickMap (ticks = offset + rate * t_s; the
// clock sync supplies offset and rate) and handed to a StepSink in chunks.
#pragma once

#include <cstddef>
#include <cstdint>

#include "core/joint_segment.hpp"

namespace feedloop::stepgen {

// Print time (s) -> MCU ticks.
struct TickMap {
  double offset_ticks = 0.0;
  double ticks_per_s = 20e6;
  double ticks(double t_s) const { return offset_ticks + ticks_per_s * t_s; }
};

// Receives exact step times (MCU ticks, not rounded) in time order.
class StepSink {
 public:
  virtual ~StepSink() = default;
  virtual void on_steps(const double* ticks, const int8_t* directions, size_t n) = 0;
};

class StepGenerator {
 public:
  // Owner: the thread that feeds segments (planner/engine). Not thread-safe.
  void configure(double steps_per_mm, TickMap map, StepSink* sink);
  void set_tick_map(TickMap map) { map_ = map; }
  // Sets the current position (no steps): n = round(pos_mm * steps_per_mm).
  void set_position_mm(double pos_mm);

  // RT-safe: no allocation. Segments must be contiguous in time and position.
  void add_segment(const JointSegment& seg);
  // Hands buffered steps to the sink.
  void flush();

  int64_t position_steps() const { return n_; }
  uint64_t steps_emitted() const { return steps_total_; }
  double steps_per_mm() const { return steps_per_mm_; }

 private:
  void quadratic_piece(double t0_s, double a, double b, double c, double tau_a, double tau_b);
  void cubic_piece(double t0_s, double a, double b, double c, double e, double tau_a,
                   double tau_b);
  void emit(double t_s, int8_t dir) {
    ticks_[count_] = map_.ticks(t_s);
    dirs_[count_] = dir;
    if (++count_ == kChunk) flush();
  }

  static constexpr size_t kChunk = 256;
  double steps_per_mm_ = 80.0;
  TickMap map_;
  StepSink* sink_ = nullptr;
  int64_t n_ = 0;
  uint64_t steps_total_ = 0;
  size_t count_ = 0;
  double ticks_[kChunk] = {};
  int8_t dirs_[kChunk] = {};
};

}  // namespace feedloop::stepgen
