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

}  // namespace feedloop::planner
