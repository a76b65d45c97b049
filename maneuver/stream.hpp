// Output maneuvering on a path that arrives while it is being followed: what a daemon's servo
// thread runs. The planner thread releases waypoints one by one; each may carry the corner weight
// k_n (Eq. 64-66) of the one before it, known once its own segment's direction is. A waypoint
// pushed again at the same position updates the newest one's extruder position. The servo thread appends them to a
// fixed-capacity window and follows the window with the controller of controller.hpp, exactly as
// ManeuverServo follows a whole PiecewiseLinearPath with split steps (no segment can be skipped).
//
// The newest waypoint of the window is always treated as a stop (k = 1): if the planner falls
// behind, the extruder slows down towards the end of the known path and holds there (v_s = 0,
// the controller then regulates z_1 to 0) until more waypoints arrive; it then leaves the waypoint
// it stopped at as from a stop (k = 1), whatever k the update brought. Nothing here allocates
// after construction.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "maneuver/controller.hpp"

namespace feedloop::maneuver {

struct StreamWaypoint {
  Vec3 p_m = Vec3::Zero();  // p_n, metres
  double k = 1.0;           // corner weight at p_n (Eq. 66); 1 where the path stops
  double e_mm = 0.0;        // extruder position at p_n (interpolated along the segment)
  int line = 0;             // G-code line of the move that ends here
  double k_prev = -1.0;     // >= 0: the corner weight of the previous waypoint, now known (set as
                            // this one is appended, so the servo never sees one without the other)
};

// The speed assignment of a streamed path: the profile and its parameters (the corner weights
// come with the waypoints).
struct StreamSpeed {
  SpeedProfile profile = SpeedProfile::sharp_corner_arc;
  SpeedParams params{};
};

// Waypoints n = first()..last() (absolute numbering from the first waypoint ever pushed); segment
// n runs from p_{n-1} to p_n, as in path.hpp.
class PathWindow {
 public:
  PathWindow(size_t capacity, Parameterization param);

  void clear();
  size_t capacity() const { return pts_.size(); }
  size_t size() const { return empty() ? 0 : static_cast<size_t>(last_ - first_ + 1); }
  bool empty() const { return last_ < first_; }
  bool full() const { return size() == capacity(); }
  uint64_t first() const { return first_; }
  uint64_t last() const { return last_; }

  // Appends p_{last+1}. A waypoint closer than min_segment_m to the last one only updates its k,
  // e and line (a zero-length segment has no direction). False when full (nothing changes).
  bool push(const StreamWaypoint& w, double min_segment_m = 1e-9);
  // Sets the corner weight of waypoint n (the servo marks a waypoint where it stopped as a stop).
  void set_k(uint64_t n, double k) { pts_[n % pts_.size()].w.k = k; }
  // Forgets waypoints before n (keeps at least the newest).
  void release_before(uint64_t n);

  const StreamWaypoint& waypoint(uint64_t n) const { return pts_[n % pts_.size()].w; }
  const Vec3& point(uint64_t n) const { return waypoint(n).p_m; }
  double theta(uint64_t n) const { return pts_[n % pts_.size()].theta; }
  double s_m(uint64_t n) const { return pts_[n % pts_.size()].s_m; }
  const Vec3& dyd(uint64_t n) const { return pts_[n % pts_.size()].dyd; }  // segment n, n > first
  Vec3 yd(double theta, uint64_t n) const { return point(n - 1) + dyd(n) * (theta - this->theta(n - 1)); }
  double arc_length(double theta, uint64_t n) const {
    return s_m(n - 1) + (theta - this->theta(n - 1)) * (s_m(n) - s_m(n - 1)) / (this->theta(n) - this->theta(n - 1));
  }
  // k at p_n as the speed assignment sees it: the newest waypoint is a stop.
  double k_effective(uint64_t n) const { return n == last_ ? 1.0 : waypoint(n).k; }

 private:
  struct Slot {
    StreamWaypoint w;
    double theta = 0.0;
    double s_m = 0.0;
    Vec3 dyd = Vec3::Zero();
  };
  Parameterization param_;
  std::vector<Slot> pts_;
  uint64_t first_ = 1, last_ = 0;  // empty
};

// v_s and dv_s/dtheta at theta on segment n of the window (speed_assignment.hpp's formulas with
// the window's corner weights).
SpeedValue stream_speed_at(const PathWindow& w, const StreamSpeed& speed, double theta, uint64_t n);

// Along- and cross-track error of z_1 = x_1 - y_d on a segment with tangent dyd (Eq. 70 with phi
// the XY heading of the segment; a segment without XY extent: cross-track is the XY norm).
struct TrackError {
  double along_m = 0.0;
  double cross_m = 0.0;
};
TrackError track_error(const Vec3& z1_m, const Vec3& dyd);

class StreamServo {
 public:
  // The window, speed and controller must outlive the servo.
  StreamServo(PathWindow& window, const StreamSpeed& speed, const ManeuverController& ctl);

  // Starts (or restarts) holding waypoint n of the window.
  void start_at(uint64_t n);
  // The oldest waypoint the servo may still need (the arc variant looks back reach_m): the owner
  // may release the window's waypoints before it.
  uint64_t oldest_needed() const;
  // One period: the voltages [V_x, V_y, V'_z] to hold for period_s. While the window has no
  // segment ahead it holds the plant at the last waypoint (holding() is then true).
  Vec3 update(const PlantState& measured, double period_s);

  // At the newest waypoint of the window with nothing ahead (holding).
  bool holding() const { return hold_; }
  uint64_t segment() const { return n_; }  // segment being followed (or, holding, the waypoint held)
  const ManeuverState& state() const { return c_; }
  const ManeuverOutput& last() const { return last_; }
  double s_m() const { return s_m_; }         // distance along the path at theta
  double e_mm() const { return e_mm_; }       // extruder position at theta
  uint64_t segments_entered() const { return entered_; }
  TrackError error() const { return err_; }   // at the latest sample

 private:
  ManeuverState rk4(const PlantState& x, const ManeuverState& c, uint64_t n, double h) const;
  ManeuverOutput eval(const PlantState& x, const ManeuverState& c, uint64_t n) const;
  void update_position();

  PathWindow& window_;
  const StreamSpeed& speed_;
  const ManeuverController& ctl_;
  ManeuverState c_;
  uint64_t n_ = 0;      // segment n (from p_{n-1} to p_n) when following; the held waypoint when holding
  bool hold_ = true;
  uint64_t entered_ = 0;
  double s_m_ = 0.0;
  double e_mm_ = 0.0;
  TrackError err_;
  ManeuverOutput last_;
};

}  // namespace feedloop::maneuver
