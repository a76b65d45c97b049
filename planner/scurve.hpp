// Jerk-limited speed changes for the S-curve profile, in closed form. A change between speeds
// v_lo and v_hi (dv = v_hi - v_lo) that starts and ends at zero acceleration, with jerk J and peak
// acceleration A, lasts at least
//   T(dv) = dv / A + A / J   (dv >= A^2 / J: the acceleration reaches A)
//   T(dv) = 2 sqrt(dv / J)   (otherwise: triangular acceleration, peak sqrt(J dv))
// and, being symmetric, covers D(v_lo, v_hi) = (v_lo + v_hi) T(dv) / 2.
// The lookahead uses these instead of v^2 = v_0^2 + 2 a L when the S-curve is selected:
//   reach: the highest v_hi with D(v_lo, v_hi) <= L. With x = sqrt(dv), the triangular case is
//     the depressed cubic x^3 + 2 v_lo x - L sqrt(J) = 0 (one real root, Cardano); the other
//     case is the quadratic dv^2 / (2A) + dv (v_lo / A + A / (2J)) + v_lo A / J - L = 0.
//   peak: the highest cruise speed v_c with D(v_0, v_c) + D(v_1, v_c) <= L (bisection).
#pragma once

namespace feedloop::planner {

double scurve_min_time(double dv, double accel_mm_s2, double jerk_mm_s3);
double scurve_distance(double v_lo, double v_hi, double accel_mm_s2, double jerk_mm_s3);
double scurve_reach(double v_lo, double length_mm, double accel_mm_s2, double jerk_mm_s3);
double scurve_peak(double v0, double v1, double length_mm, double accel_mm_s2, double jerk_mm_s3);

}  // namespace feedloop::planner
