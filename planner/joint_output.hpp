// Joint-space output of final moves: JointSegments (core/joint_segment.hpp, cubic in time) per
// joint, the contract with step generation. Joints 0..2 are the motors of the kinematics, joint 3
// the extruder.
//   cartesian / corexy: q = M x is linear, so every profile piece maps exactly onto one segment
//     per joint (quadratic for trapezoid phases, cubic for S-curve jerk phases):
//     c0 = M (x0 + u s0), c1 = M u v0, c2 = M u a0 / 2, c3 = M u j / 6.
//   delta: exact IK positions q and velocities qdot (Eq. 9-10) at the ends of every servo period
//     (an absolute grid k * period, also split at profile piece boundaries) joined by cubic
//     Hermite pieces: c2 = (3 dq/h - 2 v0 - v1)/h, c3 = (v0 + v1 - 2 dq/h)/h^2.
//   extruder: linear in the path distance, exact per piece.
#pragma once

#include "core/joint_segment.hpp"
#include "planner/kinematics.hpp"
#include "planner/move.hpp"

namespace feedloop::planner {

inline constexpr int kJoints = 4;  // 3 motors + extruder

class JointSink {
 public:
  virtual ~JointSink() = default;
  virtual void on_joint_segment(int joint, const JointSegment& segment) = 0;
};

class JointEmitter {
 public:
  JointEmitter(const Kinematics& kinematics, double servo_period_s);
  // Emits the segments of one move, in time order per joint. RT-safe (no allocation).
  void emit(const PlannedMove& move, JointSink& sink) const;

 private:
  void emit_linear(const PlannedMove& m, JointSink& sink) const;
  void emit_hermite(const PlannedMove& m, JointSink& sink) const;
  const Kinematics& kin_;
  double period_s_;
};

}  // namespace feedloop::planner
