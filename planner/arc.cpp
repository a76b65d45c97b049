// Arc splitting (see arc.hpp).
#include "planner/arc.hpp"

#include <algorithm>  // std::max, std::clamp
#include <cmath>      // atan2, hypot, acos, ceil
#include <cstdio>     // snprintf

namespace feedloop::planner {

namespace {
constexpr double kPi = 3.14159265358979323846;
}

Result<ArcPlan> plan_arc(const Vec4& start, const Vec4& end, bool clockwise, bool use_r, double i_mm,
                         double j_mm, double r_mm, double tolerance_mm) {
  const double p1 = start[kX], q1 = start[kY], p2 = end[kX], q2 = end[kY];
  double ox = i_mm, oy = j_mm;  // offset start -> centre
  if (use_r) {
    const double dx = p2 - p1, dy = q2 - q1, d = std::hypot(dx, dy);
    if (d < 1e-9) return Error{"G2/G3 with R needs an end point different from the start", {}};
    const double h2 = r_mm * r_mm - 0.25 * d * d;
    if (h2 < -1e-6 * d * d || r_mm == 0.0) {
      char buf[120];
      std::snprintf(buf, sizeof buf, "G2/G3 radius R%.4g is too small for a chord of %.4g mm", r_mm, d);
      return Error{buf, {}};
    }
    // Marlin gcode/motion/G2_G3.cpp: e = clockwise ^ (r < 0) ? -1 : 1
    const double e = (clockwise != (r_mm < 0.0)) ? -1.0 : 1.0;
    const double h = std::sqrt(std::max(0.0, h2));
    const double cx = 0.5 * (p1 + p2) + e * h * (-dy / d), cy = 0.5 * (q1 + q2) + e * h * (dx / d);
    ox = cx - p1;
    oy = cy - q1;
  }
  ArcPlan a;
  a.center_x_mm = p1 + ox;
  a.center_y_mm = q1 + oy;
  a.radius_mm = std::hypot(ox, oy);
  if (a.radius_mm < 1e-6) return Error{"G2/G3 arc has zero radius (I and J are 0)", {}};
  const double rx = -ox, ry = -oy;                            // centre -> start
  const double tx = p2 - a.center_x_mm, ty = q2 - a.center_y_mm;  // centre -> end
  const double end_radius = std::hypot(tx, ty);
  if (std::abs(end_radius - a.radius_mm) > std::max(0.05, 1e-3 * a.radius_mm)) {
    char buf[160];
    std::snprintf(buf, sizeof buf, "G2/G3 end point is not on the arc (radius %.4g at the start, %.4g at the end)",
                  a.radius_mm, end_radius);
    return Error{buf, {}};
  }
  a.start_angle_rad = std::atan2(ry, rx);
  double sweep = std::atan2(rx * ty - ry * tx, rx * tx + ry * ty);  // (-pi, pi]
  if (clockwise) {
    if (sweep >= -1e-12) sweep -= 2.0 * kPi;
  } else {
    if (sweep <= 1e-12) sweep += 2.0 * kPi;
  }
  // start == end with I/J: a full circle; otherwise a tiny wrap means a nearly full one too.
  a.sweep_rad = sweep;
  const double tol = std::clamp(tolerance_mm, 1e-6, a.radius_mm);
  const double max_phi = 2.0 * std::acos(1.0 - tol / a.radius_mm);
  a.segments = std::max(1, static_cast<int>(std::ceil(std::abs(sweep) / max_phi - 1e-9)));
  return a;
}

Vec4 arc_point(const ArcPlan& arc, const Vec4& start, const Vec4& end, int k) {
  if (k >= arc.segments) return end;
  const double f = static_cast<double>(k) / arc.segments;
  const double ang = arc.start_angle_rad + f * arc.sweep_rad;
  Vec4 p;
  p[kX] = arc.center_x_mm + arc.radius_mm * std::cos(ang);
  p[kY] = arc.center_y_mm + arc.radius_mm * std::sin(ang);
  p[kZ] = start[kZ] + f * (end[kZ] - start[kZ]);
  p[kE] = start[kE] + f * (end[kE] - start[kE]);
  return p;
}

}  // namespace feedloop::planner
