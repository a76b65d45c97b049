#include "bench/control/trajectories.hpp"

#include <cmath>    // cos, sin, atan2
#include <cstdio>   // snprintf

namespace feedloop::bench {

namespace {
constexpr double kPi = 3.14159265358979323846;

std::string g1(double x, double y, double f_mm_min) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "G1 X%.4f Y%.4f F%.1f", x, y, f_mm_min);
  return buf;
}
}  // namespace

Path circle_path(double cx_mm, double cy_mm, double radius_mm, int segments) {
  Path p;
  const double phase = kPi / segments;  // half a chord past angle 0
  for (int k = 0; k <= segments; ++k) {
    const double a = phase + 2.0 * kPi * (k % segments) / segments;
    p.vertices_mm.push_back({cx_mm + radius_mm * std::cos(a), cy_mm + radius_mm * std::sin(a)});
  }
  return p;
}

Path star_path(double cx_mm, double cy_mm, double outer_mm, double inner_mm) {
  Path p;
  for (int k = 0; k <= 10; ++k) {
    const double a = kPi / 2.0 + kPi / 5.0 * (k % 10);
    const double r = (k % 2 == 0) ? outer_mm : inner_mm;
    p.vertices_mm.push_back({cx_mm + r * std::cos(a), cy_mm + r * std::sin(a)});
  }
  return p;
}

std::vector<std::string> path_gcode(const Path& path, double speed_mm_s, double z_mm) {
  std::vector<std::string> g{"G21", "G90", "M83", "G28"};  // homed first (the default refuses moves before)
  const auto& v0 = path.vertices_mm.front();
  char buf[96];
  if (z_mm >= 0.0) {
    std::snprintf(buf, sizeof buf, "G1 X%.4f Y%.4f Z%.4f F%.1f", v0[0], v0[1], z_mm, kTravelSpeed_mm_s * 60.0);
    g.emplace_back(buf);
  } else {
    g.push_back(g1(v0[0], v0[1], kTravelSpeed_mm_s * 60.0));
  }
  std::snprintf(buf, sizeof buf, "G4 P%.0f", kDwell_ms);
  g.emplace_back(buf);
  for (size_t i = 1; i < path.vertices_mm.size(); ++i)
    g.push_back(g1(path.vertices_mm[i][0], path.vertices_mm[i][1], speed_mm_s * 60.0));
  return g;
}

std::vector<double> turn_angles_rad(const Path& path) {
  std::vector<double> out;
  const auto& v = path.vertices_mm;
  for (size_t i = 1; i + 1 < v.size(); ++i) {
    const double a_in = std::atan2(v[i][1] - v[i - 1][1], v[i][0] - v[i - 1][0]);
    const double a_out = std::atan2(v[i + 1][1] - v[i][1], v[i + 1][0] - v[i][0]);
    double d = std::fabs(a_out - a_in);
    if (d > kPi) d = 2.0 * kPi - d;
    out.push_back(d);
  }
  return out;
}

}  // namespace feedloop::bench
