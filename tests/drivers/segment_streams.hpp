// Random joint-segment streams for the step-generation tests and benchmarks: trapezoid moves
// (quadratic pieces, with reversals, very slow and very fast moves) and chains of cubic Hermite
// pieces (as the planner emits for delta joints).
#pragma once

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "core/joint_segment.hpp"

namespace feedloop::testing {

// Appends a rest-to-rest trapezoid move of `dist_mm` (signed) starting at t_s, pos_mm.
inline void append_trapezoid(std::vector<JointSegment>& out, double& t_s, double& pos_mm,
                             double dist_mm, double v_mm_s, double a_mm_s2) {
  const double d = std::fabs(dist_mm), sgn = dist_mm < 0 ? -1.0 : 1.0;
  if (d == 0.0) return;
  double t_acc = v_mm_s / a_mm_s2;
  double d_acc = 0.5 * a_mm_s2 * t_acc * t_acc;
  if (2.0 * d_acc > d) {  // triangle
    t_acc = std::sqrt(d / a_mm_s2);
    d_acc = 0.5 * d;
    v_mm_s = a_mm_s2 * t_acc;
  }
  const double t_cruise = (d - 2.0 * d_acc) / v_mm_s;
  out.push_back({t_s, t_acc, pos_mm, 0.0, sgn * 0.5 * a_mm_s2, 0.0});
  t_s += t_acc;
  pos_mm += sgn * d_acc;
  if (t_cruise > 0.0) {
    out.push_back({t_s, t_cruise, pos_mm, sgn * v_mm_s, 0.0, 0.0});
    t_s += t_cruise;
    pos_mm += sgn * v_mm_s * t_cruise;
  }
  out.push_back({t_s, t_acc, pos_mm, sgn * v_mm_s, -sgn * 0.5 * a_mm_s2, 0.0});
  t_s += t_acc;
  pos_mm += sgn * d_acc;
}

// A printing-like stream: moves of 0.2-40 mm at 5-300 mm/s, 500-6000 mm/s^2, random direction,
// with a few very slow (0.05 mm/s) and very fast (600 mm/s) moves.
inline std::vector<JointSegment> trapezoid_stream(std::mt19937_64& rng, int moves) {
  std::vector<JointSegment> out;
  std::uniform_real_distribution<double> u(0.0, 1.0);
  double t = 0.01, pos = 0.0;
  for (int i = 0; i < moves; ++i) {
    double dist = 0.2 + 40.0 * u(rng) * u(rng);
    if (u(rng) < 0.5) dist = -dist;
    double v = 5.0 + 295.0 * u(rng);
    const double a = 500.0 + 5500.0 * u(rng);
    const double r = u(rng);
    if (r < 0.03) { v = 0.05; dist = std::copysign(0.05, dist); }
    else if (r < 0.06) v = 600.0;
    append_trapezoid(out, t, pos, dist, v, a);
    if (u(rng) < 0.3) t += 0.05 * u(rng);  // pause
    // Pause as an explicit still segment so the stream stays contiguous.
    if (!out.empty() && out.back().end_s() < t) out.push_back({out.back().end_s(), t - out.back().end_s(), pos, 0, 0, 0});
  }
  return out;
}

// Quadratic pieces that reverse inside the segment (velocity zero crossing mid-piece).
inline std::vector<JointSegment> reversal_stream(std::mt19937_64& rng, int n) {
  std::vector<JointSegment> out;
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  double t = 0.0, pos = 0.0, v = 0.0;
  for (int i = 0; i < n; ++i) {
    const double dur = 0.002 + 0.05 * std::fabs(u(rng));
    const double acc = 4000.0 * u(rng);
    out.push_back({t, dur, pos, v, 0.5 * acc, 0.0});
    pos = out.back().position_mm(t + dur);
    v = out.back().velocity_mm_s(t + dur);
    t += dur;
    if (std::fabs(v) > 300.0) v = std::copysign(300.0, v) * 0.9;  // keep speeds sane (jump in v ok)
  }
  return out;
}

// C1 chain of cubic Hermite pieces of 1 ms (delta-like joints), random smooth path.
inline std::vector<JointSegment> cubic_stream(std::mt19937_64& rng, int n, double period_s = 1e-3) {
  std::vector<JointSegment> out;
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  double t = 0.0, p0 = 0.0, v0 = 0.0;
  double v_target = 0.0;
  for (int i = 0; i < n; ++i) {
    if (i % 50 == 0) v_target = 200.0 * u(rng);
    const double v1 = v0 + std::clamp(v_target - v0, -5.0, 5.0) + 2.0 * u(rng);
    const double p1 = p0 + 0.5 * (v0 + v1) * period_s + 1e-4 * u(rng);
    const double h = period_s;
    // Hermite coefficients: p(tau) = p0 + v0 tau + c2 tau^2 + c3 tau^3
    const double c2 = (3.0 * (p1 - p0) / h - 2.0 * v0 - v1) / h;
    const double c3 = (2.0 * (p0 - p1) / h + v0 + v1) / (h * h);
    out.push_back({t, h, p0, v0, c2, c3});
    t += h;
    p0 = p1;
    v0 = v1;
  }
  return out;
}

}  // namespace feedloop::testing
