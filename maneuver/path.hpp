// A piecewise-linear path y_d(theta) through waypoints p_0..p_N (output-maneuvering-cartesian
// Sect. III-B), with either of two parameterisations of the path variable theta:
//   unit:       theta_n - theta_{n-1} = 1, the paper's choice (Eq. 24-25);
//   arc_length: theta_n - theta_{n-1} = ||p_n - p_{n-1}||, so theta is the distance along the
//               path in metres and dy_d/dtheta is the unit tangent (the paper's Sect. V-A
//               suggestion). A fixed time step then advances theta by about speed * dt whatever
//               the segment lengths are.
// On segment n (theta in [theta_{n-1}, theta_n)), Eq. 21 and Eq. 22:
//   y_d(theta) = (p_n - p_{n-1}) (theta - theta_{n-1}) / (theta_n - theta_{n-1}) + p_{n-1}
//   dy_d/dtheta = (p_n - p_{n-1}) / (theta_n - theta_{n-1}),   d^2 y_d/dtheta^2 = 0 (Eq. 23).
// Segments are numbered n = 1..N as in the paper. Evaluation allocates nothing.
#pragma once

#include <cstddef>
#include <vector>

#include "core/result.hpp"
#include "maneuver/printer_model.hpp"

namespace feedloop::maneuver {

enum class Parameterization { unit, arc_length };

class PiecewiseLinearPath {
 public:
  // Consecutive waypoints closer than min_segment_m are merged (a zero-length segment has no
  // direction). Errors: fewer than two distinct waypoints, or a non-finite coordinate.
  static Result<PiecewiseLinearPath> create(const std::vector<Vec3>& waypoints_m,
                                            Parameterization param, double min_segment_m = 1e-9);

  Parameterization parameterization() const { return param_; }
  size_t segments() const { return points_.size() - 1; }         // N
  const Vec3& point(size_t n) const { return points_[n]; }        // p_n, n = 0..N
  double theta(size_t n) const { return theta_[n]; }              // theta_n, n = 0..N
  double theta_end() const { return theta_.back(); }
  double arc_length_at(size_t n) const { return s_[n]; }          // distance from p_0 to p_n, m
  double length_m() const { return s_.back(); }
  double segment_length_m(size_t n) const { return s_[n] - s_[n - 1]; }  // ||Delta_n||, n = 1..N

  // The segment n in 1..N with theta in [theta_{n-1}, theta_n) (clamped to 1 and N).
  size_t segment_at(double theta) const;
  // Eq. 21 on segment n, extended along the segment's line beyond its ends.
  Vec3 yd(double theta, size_t n) const {
    return points_[n - 1] + dyd_[n] * (theta - theta_[n - 1]);
  }
  const Vec3& dyd(size_t n) const { return dyd_[n]; }            // Eq. 22 (Eq. 25 when unit)
  // Distance along the path at theta on segment n (metres, for either parameterisation).
  double arc_length(double theta, size_t n) const {
    return s_[n - 1] + (theta - theta_[n - 1]) * (s_[n] - s_[n - 1]) / (theta_[n] - theta_[n - 1]);
  }
  // alpha_n of Eq. 64 between Delta_n and Delta_{n+1}, degrees, n = 1..N-1.
  double corner_angle_deg(size_t n) const;

 private:
  Parameterization param_ = Parameterization::unit;
  std::vector<Vec3> points_;
  std::vector<double> theta_;
  std::vector<double> s_;
  std::vector<Vec3> dyd_;  // index n = 1..N (index 0 unused)
};

}  // namespace feedloop::maneuver
