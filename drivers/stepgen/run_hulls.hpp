// The set of runs that keep steps 1..n of a run in their windows, as two convex hulls
// (docs/protocol.md section 2; O'Rourke, "An on-line algorithm for fitting straight lines
// between data ranges", CACM 24(9), 1981).
//
// Step k of a run is at  rel_k = k I + t_k A,  t_k = k (k - 1) / 2  (ticks after the run's start P,
// step_run.hpp). Divided by k, the mean interval up to step k is
//
//   m_k = rel_k / k = I + (k - 1) A / 2,                                               (1)
//
// a straight line in k with slope A / 2 and value I at k = 1. The window lo_k <= rel_k <= hi_k
// (real bounds, relative to P; an integer clock is inside exactly when it is inside the
// rounded-in integer window) is
//
//   c_k = lo_k / k  <=  I + (k - 1) A / 2  <=  d_k = hi_k / k,                         (2)
//
// so a run is a line that passes above every point (k, c_k) and below every point (k, d_k). It is
// above all points (k, c_k) exactly when it is above their upper convex hull, and below all
// points (k, d_k) exactly when below their lower convex hull. For a slope s = A / 2 the range of I
// is therefore
//
//   I_min(s) = max over the upper hull of  c_k - (k - 1) s,
//   I_max(s) = min over the lower hull of  d_k - (k - 1) s,                             (3)
//
// each attained at the hull vertex where the edge slopes cross s (found by walking from the
// vertex of the previous query: consecutive queries have close slopes). Points arrive in order
// of k, so each hull is Andrew's monotone chain: a point enters once and leaves at most once,
// O(1) amortised per step. I_min is convex in s and I_max concave, so F(s) = I_min(s) - I_max(s)
// is convex and the feasible slopes (F <= 0) form one interval.
//
// The hulls are in double precision (relative rounding about 1e-16 of the mean interval, far
// below a tick). The compressor settles the integer range of I at the vertex the hull names with
// the exact test of its fast path (integer clock against the window's real bound), and checks
// every run against every window before it leaves (step_compressor.hpp).
//
// Owner: the compressor that holds it. RT-safe after configure() (no allocation).
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdlib>  // std::malloc, std::free
#include <memory>

namespace feedloop::stepgen {

class RunHulls {
 public:
  // One side of (3) at slope s: the bound on I, its derivative in s (-(k - 1) of the vertex)
  // and the vertex's step k.
  struct Bound {
    double value = 0.0;
    double slope = 0.0;
    uint32_t k = 0;
  };

  // Room for steps 1..max_points. Not RT-safe (allocates).
  void configure(size_t max_points) {
    const size_t cap = max_points + 1;
    upper_.reset(cap);
    lower_.reset(cap);
    clear();
  }
  void clear() {
    upper_.n = lower_.n = 0;
    upper_.finger = lower_.finger = 0;
    points_ = 0;
  }
  // Points in the hulls (steps 1..points()).
  uint32_t points() const { return points_; }

  // Adds steps points()+1 .. n; bounds(k) returns the bounds {c_k, d_k} of (2). The two top
  // vertices of each chain stay in registers: a point that pops nothing (most) loads nothing.
  template <class Bounds>
  void extend(uint32_t n, Bounds bounds) {
    if (n <= points_) return;
    Point* u = upper_.v.get();
    Point* l = lower_.v.get();
    uint32_t nu = upper_.n, nl = lower_.n;
    Point u1{}, u2{}, l1{}, l2{};  // second and top vertex of each chain (when it has them)
    if (nu >= 2) u1 = u[nu - 2];
    if (nu >= 1) u2 = u[nu - 1];
    if (nl >= 2) l1 = l[nl - 2];
    if (nl >= 1) l2 = l[nl - 1];
    for (uint32_t k = points_ + 1; k <= n; ++k) {
      const auto [c, d] = bounds(k);
      const double x = k;
      push<+1>(u, nu, u1, u2, {x, c});
      push<-1>(l, nl, l1, l2, {x, d});
    }
    upper_.n = nu;
    lower_.n = nl;
    points_ = n;
  }

  // I_min(s): the upper hull of the lower points (k, c_k).
  Bound lower_bound(double s) { return query<+1>(upper_, s); }
  // I_max(s): the lower hull of the upper points (k, d_k).
  Bound upper_bound(double s) { return query<-1>(lower_, s); }

 private:
  struct FreeDeleter {
    void operator()(void* p) const { std::free(p); }
  };
  struct Point {
    double x, y;  // x = k (exact in a double), y = c_k or d_k
  };
  // Vertices in order of k. Pages a run never reaches are never touched.
  struct Chain {
    std::unique_ptr<Point[], FreeDeleter> v;
    uint32_t n = 0;
    uint32_t finger = 0;  // vertex of the last query: the next one is usually near it
    void reset(size_t cap) { v.reset(static_cast<Point*>(std::malloc(cap * sizeof(Point)))); }
  };

  // Andrew's monotone chain: appends p to the n vertices of v, whose last two are p1 and p2.
  // Side +1: upper hull (the top vertex goes when it is not strictly above the chord from the
  // one below it to p); side -1: lower hull.
  template <int Side>
  static void push(Point* v, uint32_t& n, Point& p1, Point& p2, Point p) {
    while (n >= 2 && Side * ((p2.x - p1.x) * (p.y - p1.y) - (p2.y - p1.y) * (p.x - p1.x)) >= 0.0) {
      --n;
      p2 = p1;
      if (n >= 2) p1 = v[n - 2];
    }
    v[n++] = p;
    p1 = p2;
    p2 = p;
  }

  // The vertex j maximising (Side +1) or minimising (Side -1) y_j - (x_j - 1) s: the vertex
  // where the edge slopes cross s. Walked from the last query's vertex.
  template <int Side>
  static Bound query(Chain& h, double s) {
    const Point* v = h.v.get();
    uint32_t j = h.finger < h.n ? h.finger : h.n - 1;
    // Gain of the objective from vertex j to j + 1 (side +1 maximises, -1 minimises).
    auto gain = [&](uint32_t i) {
      return Side * ((v[i + 1].y - v[i].y) - s * (v[i + 1].x - v[i].x));
    };
    if (j + 1 < h.n && gain(j) > 0.0) {
      do ++j;
      while (j + 1 < h.n && gain(j) > 0.0);
    } else {
      while (j > 0 && gain(j - 1) <= 0.0) --j;
    }
    h.finger = j;
    return {v[j].y - (v[j].x - 1.0) * s, -(v[j].x - 1.0), static_cast<uint32_t>(v[j].x)};
  }

  Chain upper_, lower_;
  uint32_t points_ = 0;
};

}  // namespace feedloop::stepgen
