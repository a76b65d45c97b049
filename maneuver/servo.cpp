// Sampled (zero-order hold) maneuvering servo (servo.hpp).
#include "maneuver/servo.hpp"

#include <algorithm>  // std::clamp

namespace feedloop::maneuver {

ManeuverServo::ManeuverServo(const PiecewiseLinearPath& path, const SpeedAssignment& speed,
                             const ManeuverController& ctl, bool split_at_waypoints)
    : path_(path), speed_(speed), ctl_(ctl), split_(split_at_waypoints) {
  reset();
}

void ManeuverServo::reset() {
  c_ = {path_.theta(0), 0.0};
  n_ = 1;
  skipped_ = 0;
  last_ = {};
}

ManeuverState ManeuverServo::rk4(const PlantState& x, const ManeuverState& c, size_t n, double h) const {
  auto f = [&](const ManeuverState& s) {
    const size_t seg = split_ ? n : path_.segment_at(s.theta);
    const ManeuverOutput o = ctl_.evaluate(path_, speed_, x, s, seg);
    return ManeuverState{o.dtheta, o.domega_s};
  };
  auto add = [](const ManeuverState& s, const ManeuverState& d, double k) {
    return ManeuverState{s.theta + k * d.theta, s.omega_s + k * d.omega_s};
  };
  const ManeuverState k1 = f(c), k2 = f(add(c, k1, 0.5 * h)), k3 = f(add(c, k2, 0.5 * h)), k4 = f(add(c, k3, h));
  return {c.theta + h / 6.0 * (k1.theta + 2.0 * k2.theta + 2.0 * k3.theta + k4.theta),
          c.omega_s + h / 6.0 * (k1.omega_s + 2.0 * k2.omega_s + 2.0 * k3.omega_s + k4.omega_s)};
}

Vec3 ManeuverServo::update(const PlantState& x, double period_s) {
  last_ = ctl_.evaluate(path_, speed_, x, c_, n_);  // Eq. 45 at the sample: held for the period
  double remaining = period_s;
  while (remaining > 0.0 && !finished()) {
    ManeuverState next = rk4(x, c_, n_, remaining);
    double h = remaining;
    if (split_ && n_ < path_.segments() && next.theta > path_.theta(n_)) {
      const double frac = (path_.theta(n_) - c_.theta) / (next.theta - c_.theta);
      h = remaining * std::clamp(frac, 0.0, 1.0);
      next = h > 0.0 ? rk4(x, c_, n_, h) : c_;
      next.theta = path_.theta(n_);  // land on the waypoint
      c_ = next;
      ++n_;
    } else {
      c_ = next;
      const size_t m = path_.segment_at(c_.theta);
      if (!split_ && m > n_ + 1) skipped_ += m - n_ - 1;
      if (!split_ || c_.theta < path_.theta(n_ - 1)) n_ = m;
    }
    remaining -= h;
  }
  return last_.w_v;
}

}  // namespace feedloop::maneuver
