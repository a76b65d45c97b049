// G2/G3 arcs in the XY plane (G17) split into straight segments within a chordal tolerance.
// Centre from I J (offsets from the start) or from R (Marlin's construction: positive R takes the
// shorter arc, negative the longer). Z and E move linearly with the angle (helix).
// Segment angle: sagitta r (1 - cos(phi/2)) <= tol  =>  phi <= 2 acos(1 - tol / r).
#pragma once

#include "core/result.hpp"
#include "planner/config.hpp"

namespace feedloop::planner {

struct ArcPlan {
  double center_x_mm = 0.0, center_y_mm = 0.0;
  double radius_mm = 0.0;
  double start_angle_rad = 0.0;
  double sweep_rad = 0.0;  // signed: > 0 counter-clockwise (G3), < 0 clockwise (G2)
  int segments = 0;
};

// start, end: machine positions. use_r selects the R form. An error for a degenerate arc (R too
// small for the chord, zero radius, R with start == end).
Result<ArcPlan> plan_arc(const Vec4& start, const Vec4& end, bool clockwise, bool use_r, double i_mm,
                         double j_mm, double r_mm, double tolerance_mm);

// The end point of segment k (1..segments) of the arc.
Vec4 arc_point(const ArcPlan& arc, const Vec4& start, const Vec4& end, int k);

}  // namespace feedloop::planner
