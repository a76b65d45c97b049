// Time parametrisation of one move in closed form: from the lookahead's entry/cruise/exit speeds
// and acceleration to the trapezoid phases and the cubic path pieces (PlannedMove::pieces), and
// evaluation of the path state at any time.
//
// Trapezoid: accel_t = (v_c - v_0)/a, decel_t = (v_c - v_1)/a,
//            cruise_t = (L - (v_c^2 - v_0^2)/2a - (v_c^2 - v_1^2)/2a) / v_c.
// S-curve (optional): every accel/decel phase keeps its speed change dv but the acceleration
// ramps with constant jerk: jerk-up tj, constant A for tc, jerk-down tj, T = 2 tj + tc,
// dv = A (tj + tc). The phase needs at least
//   T_min = dv / A_max + A_max / J   (dv >= A_max^2 / J),   T_min = 2 sqrt(dv / J)   otherwise,
// so it lasts T_s = max(T_trapezoid, T_min) and uses the smallest peak acceleration that fits:
//   A = (J T_s - sqrt(J^2 T_s^2 - 4 J dv)) / 2.
// A phase longer than its trapezoid covers (v_0 + v_1)(T_s - T)/2 more distance, taken from the
// cruise phase. The junction speeds of the lookahead stay as planned, so when the cruise phase is
// too short for that, both phases get the same fraction of their extension that the cruise
// distance allows, and the jerk exceeds J (PlannedMove::jerk_bounded is false then; Marlin's
// Bezier S-curve never lengthens phases and so never bounds the jerk). The peak acceleration never
// exceeds the move's limit; the lookahead plans with accel * scurve_accel_ratio.
#pragma once

#include "planner/move.hpp"

namespace feedloop::planner {

struct PathState {
  double s_mm = 0.0;      // distance along the move
  double v_mm_s = 0.0;
  double a_mm_s2 = 0.0;
  double jerk_mm_s3 = 0.0;
};

// Fills duration, phase times and pieces of m from length_mm, accel_mm_s2 and the three speeds.
// peak_accel_mm_s2 bounds the S-curve's peak (ignored for trapezoids). RT-safe.
void build_profile(PlannedMove& m, ProfileShape shape, double max_jerk_mm_s3, double peak_accel_mm_s2);

// Path state at time t_s relative to the move start (clamped to [0, duration]). RT-safe.
PathState path_state(const PlannedMove& m, double t_s);

}  // namespace feedloop::planner
