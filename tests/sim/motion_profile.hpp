// Test helper: piecewise constant-acceleration position profiles, including instantaneous
// velocity jumps at corners (a planner's "speed change" / junction velocity, thesis Sect. 5.4).
#pragma once

#include <vector>

namespace feedloop::sim::testing {

struct Segment {
  double v0_mm_s;     // velocity at the start of the segment (may jump from the previous end)
  double a_mm_s2;
  double duration_s;
};

class Profile {
 public:
  explicit Profile(double start_mm = 0.0) : start_mm_(start_mm) {}
  Profile& add(double v0_mm_s, double a_mm_s2, double duration_s) {
    segs_.push_back({v0_mm_s, a_mm_s2, duration_s});
    return *this;
  }
  double duration_s() const {
    double d = 0.0;
    for (const auto& s : segs_) d += s.duration_s;
    return d;
  }
  double position_mm(double t_s) const {
    double p = start_mm_;
    for (const auto& s : segs_) {
      const double dt = t_s < s.duration_s ? t_s : s.duration_s;
      p += s.v0_mm_s * dt + 0.5 * s.a_mm_s2 * dt * dt;
      t_s -= s.duration_s;
      if (t_s <= 0.0) return p;
    }
    return p;
  }
  double velocity_mm_s(double t_s) const {
    for (const auto& s : segs_) {
      if (t_s < s.duration_s) return s.v0_mm_s + s.a_mm_s2 * t_s;
      t_s -= s.duration_s;
    }
    return 0.0;
  }

 private:
  double start_mm_;
  std::vector<Segment> segs_;
};

// Accelerate from rest to v at a, cruise, then reverse at a corner whose speed change is
// dv (the velocity jumps from +v_corner to -v_corner with v_corner = dv / 2, decelerating at a
// before and accelerating after), cruise back and stop. Returns to about the start.
inline Profile corner_reversal(double v_mm_s, double a_mm_s2, double dv_mm_s, double cruise_s) {
  const double vc = dv_mm_s / 2.0 < v_mm_s ? dv_mm_s / 2.0 : v_mm_s;
  Profile p;
  p.add(0.0, a_mm_s2, v_mm_s / a_mm_s2)
      .add(v_mm_s, 0.0, cruise_s)
      .add(v_mm_s, -a_mm_s2, (v_mm_s - vc) / a_mm_s2)
      .add(-vc, -a_mm_s2, (v_mm_s - vc) / a_mm_s2)
      .add(-v_mm_s, 0.0, cruise_s)
      .add(-v_mm_s, a_mm_s2, v_mm_s / a_mm_s2)
      .add(0.0, 0.0, 0.1);
  return p;
}

}  // namespace feedloop::sim::testing
