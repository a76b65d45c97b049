// Time parametrisation of one move in closed form: from the lookahead's entry/cruise/exit speeds
// and acceleration to the trapezoid phases and the cubic path pieces (PlannedMove::pieces), and
// evaluation of the path state at any time.
//
// Trapezoid: accel_t = (v_c - v_0)/a, decel_t = (v_c - v_1)/a,
//            cruise_t = (L - (v_c^2 - v_0^2)/2a - (v_c^2 - v_1^2)/2a) / v_c.
// S-curve (optional): every speed change dv ramps the acceleration with constant jerk J:
// jerk-up tj, constant A for tc, jerk-down tj, T = 2 tj + tc, dv = A (tj + tc), starting and
// ending at zero acceleration, in the minimum time T(dv) of scurve.hpp (peak A = the move's
// acceleration limit, or sqrt(J dv) when dv is small). The lookahead already chose entry, cruise
// and exit speeds whose jerk-limited changes fit in the move, so the cruise distance
// L - D(v_0, v_c) - D(v_1, v_c) is never negative and every piece honours J and A.
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
