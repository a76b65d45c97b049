// One corner at a time: see corner_response.hpp.
#include "maneuver/corner_response.hpp"

#include <algorithm>
#include <cmath>

#include "maneuver/controller.hpp"
#include "maneuver/simulation.hpp"

namespace feedloop::maneuver {

std::vector<Vec3> corner_path(double turn_deg, int turns, double chord_m, double leg_m) {
  std::vector<Vec3> wp = {Vec3{0, 0, 0}, Vec3{leg_m, 0, 0}};
  turns = std::max(turns, 1);
  const double step = turn_deg * M_PI / 180.0 / turns;
  for (int i = 1; i <= turns; ++i) {
    const double heading = i * step, len = i == turns ? leg_m : chord_m;
    wp.push_back(wp.back() + Vec3{len * std::cos(heading), len * std::sin(heading), 0});
  }
  return wp;
}

Result<CornerResponse> corner_response(const std::vector<Vec3>& waypoints_m, SpeedProfile profile,
                                       const SpeedParams& speed) {
  auto path = PiecewiseLinearPath::create(waypoints_m, Parameterization::unit);
  if (!path) return path.error();
  auto assignment = SpeedAssignment::create(*path, profile, speed);
  if (!assignment) return assignment.error();
  const CartesianDcPlant plant;
  const ManeuverController ctl(plant, ManeuverGains{});
  SimOptions so;
  so.record_every = 1;
  so.max_time_s = 10.0 * path->length_m() / speed.m_s_m_s;
  auto res = simulate(*path, *assignment, ctl, plant, so);
  if (!res) return res.error();
  if (!res->finished || res->segment_entry_s.size() < 3)
    return Error{"the corner run did not finish", {}};
  const double t_corner = res->segment_entry_s[2];
  CornerResponse c;
  double t_peak = t_corner;
  for (const SimSample& s : res->samples) {
    const double e = std::abs(s.cross_m);
    c.iae_cross_m_s += e * so.dt_s;
    c.max_z1_m = std::max(c.max_z1_m, std::hypot(s.cross_m, s.along_m));
    if (e > c.max_cross_m) c.max_cross_m = e, t_peak = s.t_s;
  }
  for (const SimSample& s : res->samples)
    if (s.t_s > t_peak && std::abs(s.cross_m) > 0.01 * c.max_cross_m) c.settle_s = s.t_s - t_corner;
  return c;
}

}  // namespace feedloop::maneuver
