// Evaluating planned motion at any time: the Cartesian state of a move (position, velocity and
// acceleration of X Y Z E) and the exact joint positions through the kinematics; MoveTimeline
// keeps the last N final moves (fixed capacity) and finds the one covering a time.
#pragma once

#include <cstddef>
#include <vector>

#include "planner/kinematics.hpp"
#include "planner/move.hpp"

namespace feedloop::planner {

struct CartesianSample {
  Vec4 pos_mm{};
  Vec4 vel_mm_s{};
  Vec4 accel_mm_s2{};
};

// t_s is absolute print time; it is clamped to the move. RT-safe.
CartesianSample sample_move(const PlannedMove& m, double t_s);
// Exact joint positions (IK of the sampled point). RT-safe.
Joints sample_joints(const Kinematics& kin, const PlannedMove& m, double t_s);

// Ring of the most recent final moves. Owner: one thread (push and sample from the same thread).
class MoveTimeline {
 public:
  explicit MoveTimeline(size_t capacity);
  void push(const PlannedMove& m);  // drops the oldest when full. RT-safe.
  // The state at time t_s; false when t_s is not covered by the stored moves (before the oldest
  // or in a dwell gap/after the last move: then the nearest end position is returned). RT-safe.
  bool sample(double t_s, CartesianSample& out) const;
  size_t size() const { return count_; }
  void clear() { head_ = count_ = 0; }  // RT-safe

 private:
  const PlannedMove& at(size_t i) const { return ring_[(head_ + i) % ring_.size()]; }
  std::vector<PlannedMove> ring_;
  size_t head_ = 0, count_ = 0;
};

}  // namespace feedloop::planner
