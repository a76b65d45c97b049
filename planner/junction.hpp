// Cornering: the highest speed allowed at the junction of two straight moves.
//
// Junction deviation (Marlin planner.cpp, Klipper toolhead.py "approximated centripetal
// velocity"): with theta the angle between the reversed incoming direction and the outgoing one
// (cos theta = -u_prev . u_next), R = sin(theta/2) / (1 - sin(theta/2)) and
//   v_j^2 = R * jd * a,
// capped so that the approximating circle touches each move no further than its midpoint:
//   v^2 <= delta_v2 * tan(theta/2) / 4  (delta_v2 = 2 a L of each move).
// With jd = scv^2 (sqrt 2 - 1) / a_max a 90-degree corner is taken at Klipper's
// square_corner_velocity scv.
//
// Sharp-corner assignment (output-maneuvering-cartesian, Sect. III-D):
//   alpha_n = acos(Delta_{n+1} . Delta_n / (|Delta_{n+1}| |Delta_n|)) in degrees      (Eq. 64)
//   k_n = 0 below alpha_a, (alpha_n - alpha_a)/(alpha_b - alpha_a) between, 1 above (Eq. 66)
//   h(theta) = atan((theta - a_1) / a_2) / pi + 1/2                                   (Eq. 68)
// and the path speed ||Delta_n|| v_s of Eq. 67 at the corner theta = theta_n is
//   v_corner = m_s (k_n h(0) + (1 - k_n) h(1/2)),
// with m_s the programmed speed (the smaller of the two moves' cruise speeds). Eq. 63's
// constant-speed assignment is the k_n = 0 case without the sigmoid.
//
// Speed change (closed-loop-gantry-thesis Sect. 2.2, Fig. 1; Sect. 5.4 "the maximum magnitude of
// the difference between velocity before and velocity after a corner"): the corner speed v is the
// largest with |v u_next - v u_prev| <= dv_max, where the thesis measures the "magnitude of the
// vector difference between the command velocity just before and just after the corner". With
// unit XYZ directions |u_next - u_prev| = 2 sin(alpha/2) (alpha the turn angle), so
//   v = dv_max / |u_next - u_prev| = dv_max / (2 sin(alpha/2)),
// unlimited straight through (alpha = 0) and dv_max / 2 at a full reversal. This is the Euclidean
// norm of the thesis's wording, not Marlin's classic jerk, which bounds each axis's change
// separately (max_i |v u_next,i - v u_prev,i| <= jerk_i, a square corner at +-45 deg then passes
// at jerk/sin 45 = 1.41 jerk instead of jerk/sqrt 2 = 0.71 jerk). E is not part of it (as for the
// junction deviation); there is no mid-move cap, so 300 mm/s takes every corner at full speed.
#pragma once

#include "planner/config.hpp"

namespace feedloop::planner {

// u_prev, u_next: unit XYZ directions. Returns the v^2 limit (mm^2/s^2), +inf for a straight line.
double junction_deviation_v2(const double* u_prev, const double* u_next, double jd_mm,
                             double prev_accel_mm_s2, double next_accel_mm_s2,
                             double prev_delta_v2, double next_delta_v2);

double corner_angle_deg(const double* u_prev, const double* u_next);        // Eq. 64
double sharp_corner_k(double alpha_deg, const SharpCornerParams& p);          // Eq. 66
double sharp_corner_h(double theta, const SharpCornerParams& p);              // Eq. 68
// Eq. 67 evaluated at the corner: the corner speed for programmed speed m_s.
double sharp_corner_speed(double m_s_mm_s, double alpha_deg, const SharpCornerParams& p);
// Thesis Sect. 2.2: the v^2 limit (mm^2/s^2) for a velocity change of at most dv_max_mm_s
// (vector norm over XYZ); +inf for a straight line.
double speed_change_v2(const double* u_prev, const double* u_next, double dv_max_mm_s);

}  // namespace feedloop::planner
