#include "bench/control/metrics.hpp"

#include <algorithm>  // max
#include <cmath>      // hypot, sqrt, fabs
#include <cstdio>     // snprintf

namespace feedloop::bench {

namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr double kRestEps_mm = 1e-9;  // planned position unchanged between two samples

bool moved(const TrackSample& a, const TrackSample& b) {
  return std::fabs(a.ref_mm[0] - b.ref_mm[0]) > kRestEps_mm || std::fabs(a.ref_mm[1] - b.ref_mm[1]) > kRestEps_mm ||
         std::fabs(a.ref_mm[2] - b.ref_mm[2]) > kRestEps_mm;
}
}  // namespace

bool find_pattern_window(const std::vector<TrackSample>& s, int min_rest_samples, size_t& i0, size_t& i1) {
  size_t last_move = 0;
  for (size_t i = 1; i < s.size(); ++i)
    if (moved(s[i - 1], s[i])) last_move = i;
  if (last_move == 0) return false;
  i1 = last_move;  // the plan reaches the final rest in (t[i1-1], t[i1]]
  i0 = 0;
  int run = 0;
  size_t run_end = 0;
  for (size_t j = last_move; j >= 1; --j) {
    if (!moved(s[j - 1], s[j])) {
      if (run == 0) run_end = j;
      if (++run >= min_rest_samples) {
        i0 = run_end;  // at rest at t[i0], moving by t[i0 + 1]
        break;
      }
    } else {
      run = 0;
    }
  }
  return true;
}

TrackMetrics track_metrics(const std::vector<TrackSample>& s, size_t i0, size_t i1,
                           const std::optional<Circle>& circle) {
  TrackMetrics m;
  if (i1 < i0 || i1 >= s.size()) return m;
  double sum = 0, sum2 = 0, rsum2 = 0;
  for (size_t i = i0; i <= i1; ++i) {
    const double e = std::hypot(s[i].act_mm[0] - s[i].ref_mm[0], s[i].act_mm[1] - s[i].ref_mm[1]);
    sum += e;
    sum2 += e * e;
    m.e_max_mm = std::max(m.e_max_mm, e);
    if (circle) {
      const double dr = std::hypot(s[i].act_mm[0] - circle->cx_mm, s[i].act_mm[1] - circle->cy_mm) - circle->r_mm;
      rsum2 += dr * dr;
    }
  }
  m.samples = i1 - i0 + 1;
  const double n = static_cast<double>(m.samples);
  m.e_t_mm = sum / n;
  m.e_t_std_mm = std::sqrt(std::max(0.0, sum2 / n - m.e_t_mm * m.e_t_mm));
  if (circle) m.e_r_mm = std::sqrt(rsum2 / n);
  m.time_s = s[i1].t_s - s[i0].t_s;
  return m;
}

// Synthetic run: 0.2 s at rest at the origin, 0.5 s travel to (r, 0), 0.3 s rest, a true circle
// at constant angular speed for T, 0.05 s rest. The "machine" runs on a circle of radius r + dr,
// lagging by the angle phi: e_r = dr, e_t = |(r + dr) e^{-i phi} - r| at every sample (std 0);
// the travel and the rests are tracked exactly and must fall outside the window.
std::string metrics_self_test() {
  const double dt = 1e-3, r = 20.0, dr = 0.1, phi = 0.01, T = 1.4;
  std::vector<TrackSample> s;
  double t = 0;
  auto push = [&](double rx, double ry, double ax, double ay) {
    TrackSample x;
    x.t_s = t;
    x.ref_mm[0] = rx; x.ref_mm[1] = ry;
    x.act_mm[0] = ax; x.act_mm[1] = ay;
    s.push_back(x);
    t += dt;
  };
  for (int i = 0; i < 200; ++i) push(0, 0, 0, 0);
  for (int i = 1; i <= 500; ++i) push(r * i / 500.0, 0, r * i / 500.0, 0);
  for (int i = 0; i < 300; ++i) push(r, 0, r, 0);
  const size_t start = s.size() - 1;
  const int n = static_cast<int>(std::lround(T / dt));
  for (int i = 1; i <= n; ++i) {
    const double a = 2.0 * kPi * i / n;
    const double b = i < n ? a - phi : a;  // the last sample is at rest on the start again
    const double rr = i < n ? r + dr : r;
    push(r * std::cos(a), r * std::sin(a), rr * std::cos(b), rr * std::sin(b));
  }
  const size_t end = s.size() - 1;
  for (int i = 0; i < 50; ++i) push(r, 0, r, 0);

  std::string fail;
  char buf[256];
  size_t i0 = 0, i1 = 0;
  if (!find_pattern_window(s, 20, i0, i1)) return "window: no motion found";
  if (i0 != start || i1 != end) {
    std::snprintf(buf, sizeof buf, "window [%zu, %zu], expected [%zu, %zu]; ", i0, i1, start, end);
    fail += buf;
  }
  const TrackMetrics m = track_metrics(s, i0, i1, Circle{0, 0, r});
  const double e_expect = std::hypot((r + dr) * std::cos(phi) - r, (r + dr) * std::sin(phi));
  // The window's two end samples are exact (error 0): the mean is (N - 2)/N of e_expect.
  const double frac = static_cast<double>(m.samples - 2) / static_cast<double>(m.samples);
  auto check = [&](const char* what, double got, double want, double tol) {
    if (std::fabs(got - want) > tol) {
      std::snprintf(buf, sizeof buf, "%s %.6g, expected %.6g; ", what, got, want);
      fail += buf;
    }
  };
  check("e_t", m.e_t_mm, e_expect * frac, 1e-9);
  check("e_max", m.e_max_mm, e_expect, 1e-9);
  check("e_r", m.e_r_mm, dr * std::sqrt(frac), 1e-9);
  check("time", m.time_s, T, 1e-9);
  check("e_t_std", m.e_t_std_mm, e_expect * std::sqrt(frac * (1 - frac)), 1e-9);
  return fail;
}

}  // namespace feedloop::bench
