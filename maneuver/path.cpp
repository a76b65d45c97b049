// Piecewise-linear path construction and lookup (see path.hpp).
#include "maneuver/path.hpp"

#include <algorithm>  // std::upper_bound, std::clamp
#include <cmath>      // std::isfinite
#include <string>

#include "planner/junction.hpp"

namespace feedloop::maneuver {

Result<PiecewiseLinearPath> PiecewiseLinearPath::create(const std::vector<Vec3>& waypoints_m,
                                                        Parameterization param, double min_segment_m) {
  PiecewiseLinearPath p;
  p.param_ = param;
  if (!(min_segment_m > 0.0)) min_segment_m = 1e-12;  // a zero-length segment has no direction
  for (size_t i = 0; i < waypoints_m.size(); ++i) {
    const Vec3& w = waypoints_m[i];
    if (!w.allFinite())
      return Error{"waypoint " + std::to_string(i) + " has a non-finite coordinate", {}};
    if (!p.points_.empty() && (w - p.points_.back()).norm() < min_segment_m) continue;
    p.points_.push_back(w);
  }
  if (p.points_.size() < 2)
    return Error{"a path needs at least two distinct waypoints (got " + std::to_string(p.points_.size()) + ")", {}};
  const size_t n_seg = p.points_.size() - 1;
  p.theta_.assign(n_seg + 1, 0.0);
  p.s_.assign(n_seg + 1, 0.0);
  p.dyd_.assign(n_seg + 1, Vec3::Zero());
  for (size_t n = 1; n <= n_seg; ++n) {
    const Vec3 delta = p.points_[n] - p.points_[n - 1];  // Delta_n, Eq. 65
    const double len = delta.norm();
    p.s_[n] = p.s_[n - 1] + len;
    const double dtheta = param == Parameterization::unit ? 1.0 : len;
    p.theta_[n] = p.theta_[n - 1] + dtheta;
    p.dyd_[n] = delta / dtheta;  // Eq. 22
  }
  return p;
}

size_t PiecewiseLinearPath::segment_at(double th) const {
  const auto it = std::upper_bound(theta_.begin(), theta_.end(), th);
  const auto n = static_cast<size_t>(it - theta_.begin());  // first theta_n > th
  return std::clamp<size_t>(n, 1, segments());
}

double PiecewiseLinearPath::corner_angle_deg(size_t n) const {
  const Vec3 a = dyd_[n].normalized();
  const Vec3 b = dyd_[n + 1].normalized();
  return planner::corner_angle_deg(a.data(), b.data());  // Eq. 64
}

}  // namespace feedloop::maneuver
