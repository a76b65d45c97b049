// G-code of the path-following benchmark part (test_part.hpp).
#include "maneuver/test_part.hpp"

#include <cmath>
#include <cstdio>
#include <utility>
#include <vector>

namespace feedloop::maneuver {

namespace {
constexpr double kPi = 3.14159265358979323846;

using Outline = std::vector<std::pair<double, double>>;

Outline star_outline() {
  Outline p;
  p.emplace_back(6.0, 0.0);
  p.emplace_back(0.0, 0.0);
  const double r = 1.5;  // fillet at (0,40): centre (1.5, 38.5), from 180 to 90 degrees
  p.emplace_back(0.0, 40.0 - r);
  for (int i = 1; i <= 4; ++i) {
    const double a = kPi - i * (kPi / 2.0) / 4.0;
    p.emplace_back(r + r * std::cos(a), 40.0 - r + r * std::sin(a));
  }
  p.emplace_back(40.0, 40.0);
  for (int deg = 90 - 6; deg >= -90; deg -= 6) {  // half ellipse, clockwise
    const double t = deg * kPi / 180.0;
    p.emplace_back(40.0 + 25.0 * std::cos(t), 20.0 + 20.0 * std::sin(t));
  }
  p.emplace_back(28.0, 0.0);
  p.emplace_back(20.0, 10.0);
  p.emplace_back(12.0, 0.0);
  p.emplace_back(6.0, 0.0);
  return p;
}

Outline fin_outline() {
  const double bx[4] = {0.0, 25.0, 55.0, 80.0}, by[4] = {-4.0, -4.0, -30.0, 0.0};
  auto bezier = [&](double t, double& x, double& y) {
    const double u = 1.0 - t;
    const double w[4] = {u * u * u, 3.0 * u * u * t, 3.0 * u * t * t, t * t * t};
    x = y = 0.0;
    for (int i = 0; i < 4; ++i) {
      x += w[i] * bx[i];
      y += w[i] * by[i];
    }
  };
  constexpr int kChords = 24;
  Outline p;
  p.emplace_back(0.0, 0.0);
  for (int i = 0; i <= kChords; ++i) {  // bottom side, out to the tip
    double x, y;
    bezier(static_cast<double>(i) / kChords, x, y);
    p.emplace_back(x, y);
  }
  for (int i = kChords - 1; i >= 0; --i) {  // top side (mirror image), back to the left end
    double x, y;
    bezier(static_cast<double>(i) / kChords, x, y);
    p.emplace_back(x, -y);
  }
  p.emplace_back(0.0, 0.0);
  return p;
}

double outline_length_mm(const Outline& p) {
  double l = 0.0;
  for (size_t i = 1; i < p.size(); ++i)
    l += std::hypot(p[i].first - p[i - 1].first, p[i].second - p[i - 1].second);
  return l;
}
}  // namespace

double test_part_layer_length_mm(TestPart part) {
  return outline_length_mm(part == TestPart::fin ? fin_outline() : star_outline());
}

std::string test_part_gcode(const TestPartOptions& o) {
  std::string g = "; feedloop maneuver benchmark part (maneuver/test_part.hpp)\nG21\nG90\nM82\nG92 E0\n";
  Outline outline = o.part == TestPart::fin ? fin_outline() : star_outline();
  if (o.layer_length_mm > 0.0) {
    const double k = o.layer_length_mm / outline_length_mm(outline);
    const auto p0 = outline[0];
    for (auto& p : outline)
      p = {p0.first + k * (p.first - p0.first), p0.second + k * (p.second - p0.second)};
  }
  char buf[160];
  double e = 0.0;
  for (int layer = 0; layer < o.layers; ++layer) {
    const double z = o.layer_height_mm * (layer + 1);
    std::snprintf(buf, sizeof buf, ";LAYER_CHANGE\n;Z:%.3f\nG1 Z%.3f F600\n", z, z);
    g += buf;
    if (layer == 0) {
      std::snprintf(buf, sizeof buf, "G1 X%.4f Y%.4f F6000\n", o.origin_x_mm + outline[0].first,
                    o.origin_y_mm + outline[0].second);
      g += buf;
    }
    g += ";TYPE:External perimeter\nG1 F3600\n";
    for (size_t i = 1; i < outline.size(); ++i) {
      const double dx = outline[i].first - outline[i - 1].first;
      const double dy = outline[i].second - outline[i - 1].second;
      e += 0.05 * std::hypot(dx, dy);
      std::snprintf(buf, sizeof buf, "G1 X%.4f Y%.4f E%.5f\n", o.origin_x_mm + outline[i].first,
                    o.origin_y_mm + outline[i].second, e);
      g += buf;
    }
  }
  return g;
}

}  // namespace feedloop::maneuver
