// Junction speed limits (see junction.hpp for the formulas).
#include "planner/junction.hpp"

#include <algorithm>  // std::min, std::clamp
#include <cmath>      // sqrt, acos, atan
#include <limits>

namespace feedloop::planner {

namespace {
constexpr double kPi = 3.14159265358979323846;
}

double junction_deviation_v2(const double* up, const double* un, double jd_mm, double prev_accel_mm_s2,
                             double next_accel_mm_s2, double prev_delta_v2, double next_delta_v2) {
  const double cos_theta = -(up[0] * un[0] + up[1] * un[1] + up[2] * un[2]);
  const double sin_theta_d2 = std::sqrt(std::max(0.5 * (1.0 - cos_theta), 0.0));
  const double cos_theta_d2 = std::sqrt(std::max(0.5 * (1.0 + cos_theta), 0.0));
  const double one_minus_sin = 1.0 - sin_theta_d2;
  if (!(one_minus_sin > 0.0 && cos_theta_d2 > 0.0)) return std::numeric_limits<double>::infinity();
  const double r_jd = sin_theta_d2 / one_minus_sin;
  const double quarter_tan = 0.25 * sin_theta_d2 / cos_theta_d2;
  return std::min({r_jd * jd_mm * next_accel_mm_s2, r_jd * jd_mm * prev_accel_mm_s2,
                   next_delta_v2 * quarter_tan, prev_delta_v2 * quarter_tan});
}

double corner_angle_deg(const double* up, const double* un) {
  const double c = std::clamp(up[0] * un[0] + up[1] * un[1] + up[2] * un[2], -1.0, 1.0);
  return 180.0 / kPi * std::acos(c);  // Eq. 64 (unit vectors: the norms are 1)
}

double sharp_corner_k(double alpha_deg, const SharpCornerParams& p) {
  if (alpha_deg < p.alpha_a_deg) return 0.0;                                     // non-sharp
  if (alpha_deg <= p.alpha_b_deg) return (alpha_deg - p.alpha_a_deg) / (p.alpha_b_deg - p.alpha_a_deg);  // sharp
  return 1.0;                                                                    // very sharp
}

double sharp_corner_h(double theta, const SharpCornerParams& p) {
  return std::atan((theta - p.a1) / p.a2) / kPi + 0.5;  // Eq. 68
}

double sharp_corner_speed(double m_s_mm_s, double alpha_deg, const SharpCornerParams& p) {
  const double k = sharp_corner_k(alpha_deg, p);
  // Eq. 67 at theta = theta_n (second branch, theta_n - theta = 0), times ||Delta_n||.
  return m_s_mm_s * (k * sharp_corner_h(0.0, p) + (1.0 - k) * sharp_corner_h(0.5, p));
}

double speed_change_v2(const double* up, const double* un, double dv_max_mm_s) {
  // |u_next - u_prev|^2 from the differences (not 2 - 2 cos: exact for nearly straight junctions)
  double du2 = 0.0;
  for (int i = 0; i < 3; ++i) du2 += (un[i] - up[i]) * (un[i] - up[i]);
  if (!(du2 > 0.0)) return std::numeric_limits<double>::infinity();
  return dv_max_mm_s * dv_max_mm_s / du2;  // v |u_next - u_prev| <= dv_max
}

}  // namespace feedloop::planner
