// The maneuvering controller as a sampled servo: once per control period it reads the measured
// plant state, returns the voltages to hold over the period (zero-order hold), and advances its own
// states theta and omega_s over the period (Eq. 56 and Eq. 52 with the measurement held; classical
// RK4, split at waypoints when asked so that theta enters every segment). This is the shape a
// fixed-period servo thread calls; update() allocates nothing and locks nothing.
#pragma once

#include <cstddef>

#include "maneuver/controller.hpp"

namespace feedloop::maneuver {

class ManeuverServo {
 public:
  // The path, speed assignment and controller must outlive the servo.
  ManeuverServo(const PiecewiseLinearPath& path, const SpeedAssignment& speed, const ManeuverController& ctl,
                bool split_at_waypoints);

  void reset();  // theta = theta_0, omega_s = 0, segment 1

  // One period: the voltages [V_x, V_y, V'_z] to hold from now for period_s.
  Vec3 update(const PlantState& measured, double period_s);

  const ManeuverState& state() const { return c_; }
  size_t segment() const { return n_; }
  bool finished() const { return c_.theta >= path_.theta_end(); }
  const ManeuverOutput& last() const { return last_; }  // outputs of the latest update
  size_t skipped_segments() const { return skipped_; }  // segments theta jumped over

 private:
  ManeuverState rk4(const PlantState& x, const ManeuverState& c, size_t n, double h) const;

  const PiecewiseLinearPath& path_;
  const SpeedAssignment& speed_;
  const ManeuverController& ctl_;
  bool split_;
  ManeuverState c_;
  size_t n_ = 1;
  size_t skipped_ = 0;
  ManeuverOutput last_;
};

}  // namespace feedloop::maneuver
