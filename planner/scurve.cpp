// Jerk-limited speed changes (see scurve.hpp).
#include "planner/scurve.hpp"

#include <algorithm>  // std::max, std::min
#include <cmath>      // sqrt, cbrt, abs

namespace feedloop::planner {

double scurve_min_time(double dv, double A, double J) {
  dv = std::abs(dv);
  if (dv <= 0.0) return 0.0;
  if (dv >= A * A / J) return dv / A + A / J;
  return 2.0 * std::sqrt(dv / J);
}

double scurve_distance(double v_lo, double v_hi, double A, double J) {
  return 0.5 * (v_lo + v_hi) * scurve_min_time(v_hi - v_lo, A, J);
}

double scurve_reach(double v_lo, double L, double A, double J) {
  if (L <= 0.0) return v_lo;
  // triangular case: x^3 + p x - q = 0, p = 2 v_lo, q = L sqrt(J), x = sqrt(dv)  (Cardano)
  const double p = 2.0 * v_lo, q = L * std::sqrt(J);
  const double disc = std::sqrt(0.25 * q * q + p * p * p / 27.0);
  const double x = std::cbrt(0.5 * q + disc) + std::cbrt(0.5 * q - disc);
  double dv = x * x;
  if (dv > A * A / J) {
    // the acceleration saturates at A: dv^2/(2A) + dv (v_lo/A + A/(2J)) + v_lo A/J - L = 0
    const double a2 = 0.5 / A, b = v_lo / A + 0.5 * A / J, c = v_lo * A / J - L;
    dv = (-b + std::sqrt(std::max(0.0, b * b - 4.0 * a2 * c))) / (2.0 * a2);
  }
  return v_lo + std::max(0.0, dv);
}

double scurve_peak(double v0, double v1, double L, double A, double J) {
  double lo = std::max(v0, v1);
  if (scurve_distance(std::min(v0, v1), lo, A, J) >= L) return lo;
  double hi = std::min(scurve_reach(v0, L, A, J), scurve_reach(v1, L, A, J));
  for (int k = 0; k < 60 && hi - lo > 1e-9 * (1.0 + hi); ++k) {
    const double mid = 0.5 * (lo + hi);
    if (scurve_distance(v0, mid, A, J) + scurve_distance(v1, mid, A, J) <= L) lo = mid; else hi = mid;
  }
  return lo;
}

}  // namespace feedloop::planner
