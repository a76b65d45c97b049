// The thesis's test paths (closed-loop-gantry-thesis Sect. 5.2-5.4) as G-code, with fixed
// definitions (issue 5, "Benchmarks"):
//   circle: 50 chords of a circle of radius 20 mm, counter-clockwise, the first vertex half a chord
//           past angle 0 (so no vertex lies on the axes: the delta's print disc of radius 100 mm
//           still holds the circle centred at (-80, 0));
//   star:   five-pointed, 10 vertices alternating outer radius R and inner radius r, the first an
//           outer tip at 90 deg, counter-clockwise; small R 5 / r 2 mm, large R 35 / r 14 mm.
// Every program: a travel move at kTravelSpeed to the first vertex, a dwell (the pattern starts
// from rest and the travel's vibration dies out), then the closed path at the pattern speed,
// ending at rest on the first vertex.
#pragma once

#include <array>
#include <string>
#include <vector>

namespace feedloop::bench {

inline constexpr double kTravelSpeed_mm_s = 50.0;
inline constexpr double kDwell_ms = 300.0;

struct Path {
  std::vector<std::array<double, 2>> vertices_mm;  // closed: the last equals the first
};

Path circle_path(double cx_mm, double cy_mm, double radius_mm, int segments);
Path star_path(double cx_mm, double cy_mm, double outer_mm, double inner_mm);

// G21/G90, travel to the first vertex (at z_mm when z_mm >= 0; else Z untouched), dwell, then the
// path at speed_mm_s.
std::vector<std::string> path_gcode(const Path& path, double speed_mm_s, double z_mm);

// Turn angle (rad, 0 = straight on) at every interior vertex of the closed path, in order from the
// second vertex; the closing vertex (back at the start) is left out: the path stops there.
std::vector<double> turn_angles_rad(const Path& path);

}  // namespace feedloop::bench
