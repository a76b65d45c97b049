// Time parametrisation of one move in closed form: from the lookahead's entry/cruise/exit speeds
// and acceleration to the trapezoid phases and the cubic path pieces (PlannedMove::pieces), and
// evaluation of the path state at any time.
//
// Trapezoid: accel_t = (v_c - v_0)/a, decel_t = (v_c - v_1)/a,
//            cruise_t = (L - (v_c^2 - v_0^2)/2a - (v_c^2 - v_1^2)/2a) / v_c.
// S-curve (optional): every accel/decel phase keeps its duration T and speed change dv (so the
// distance (v_0 + v_1) T / 2, the lookahead plan and the print time are unchanged, as in Marlin's
// Bezier S-curve) but the acceleration ramps with constant jerk: jerk-up tj, constant A for tc,
// jerk-down tj, with T = 2 tj + tc and dv = A (tj + tc). A is the smallest peak acceleration that
// honours the jerk bound J: A = (J T - sqrt(J^2 T^2 - 4 J dv)) / 2 when J T^2 >= 4 dv; a phase too
// short for that uses a triangular acceleration (A = 2 dv / T, jerk 4 dv / T^2 > J). The peak
// never exceeds the move's acceleration limit (the planner plans with accel * scurve_accel_ratio).
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
