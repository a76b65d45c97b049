// The few step windows a run's candidate is fitted to (docs/protocol.md section 2).
//
// Step k of a run is at  rel_k = k I + t_k A,  t_k = k (k - 1) / 2  (ticks after the run's start P,
// step_run.hpp). Divided by k, the mean interval up to step k is
//
//   m_k = rel_k / k = I + (k - 1) A / 2,                                               (1)
//
// a straight line in k with slope A / 2 and value I at k = 1. The window lo_k <= rel_k <= hi_k
// (real bounds, relative to P) is
//
//   c_k = lo_k / k  <=  I + (k - 1) A / 2  <=  d_k = hi_k / k,                         (2)
//
// so for an add A the windows of a set S of steps leave the interval range
//
//   I_min(A) = max over S of  c_k - h_k A,   I_max(A) = min over S of  d_k - h_k A,
//   h_k = (k - 1) / 2.                                                                  (3)
//
// I_min is convex in A and I_max concave, so F(A) = I_min(A) - I_max(A) is convex, and the adds
// it leaves (F <= 0) form one interval. A set S that leaves no (I, A) proves that the whole run
// leaves none; a candidate that S leaves is checked against every step of the run, and the first
// step it misses joins S (constraint generation). S stays small: a run's candidate is pinned by two
// or three windows, and the steps that end up in S are the ones that bind.
//
// Owner: the compressor that holds it. Fixed capacity, no allocation (RT-safe).
#pragma once

#include <algorithm>  // std::min, std::max
#include <array>
#include <cstdint>
#include <limits>

namespace feedloop::stepgen {

namespace detail {
// 1/m (m >= 1), from a table for the small m of most runs: a division costs more than the rest
// of a window's bookkeeping or of a step's check.
inline constexpr auto kReciprocals = [] {
  std::array<double, 1024> t{};
  for (uint32_t i = 1; i < t.size(); ++i) t[i] = 1.0 / static_cast<double>(i);
  return t;
}();
inline double reciprocal(uint32_t m) {
  return m < kReciprocals.size() ? kReciprocals[m] : 1.0 / static_cast<double>(m);
}
}  // namespace detail

class ActiveWindows {
 public:
  static constexpr uint32_t kCapacity = 32;

  // One side of (3) at an add: the bound on I, its derivative in A (-h_k) and the step k.
  struct Bound {
    double value = 0.0;
    double slope = 0.0;
    uint32_t k = 0;
  };
  struct Range {
    Bound lower, upper;  // I_min(A) and I_max(A)
  };

  void clear() {
    size_ = 0;
    a_lo_ = -std::numeric_limits<double>::infinity();
    a_hi_ = std::numeric_limits<double>::infinity();
  }
  uint32_t size() const { return size_; }
  bool full() const { return size_ == kCapacity; }
  bool contains(uint32_t k) const {
    for (uint32_t j = 0; j < size_; ++j)
      if (k_[j] == k) return true;
    return false;
  }
  // Adds step k's window lo_rel <= rel_k <= hi_rel (ticks after the run's start). Needs room.
  // The real adds the windows leave (F <= 0 and I >= 1) narrow with it: every pair of windows
  // j, l bounds A by  c_j - h_j A <= d_l - h_l A,  and I >= 1 by  1 <= d_l - h_l A.
  void add(uint32_t k, double lo_rel, double hi_rel) {
    const double r = reciprocal(k);
    const double c = lo_rel * r, d = hi_rel * r, h = 0.5 * (static_cast<double>(k) - 1.0);
    for (uint32_t j = 0; j < size_; ++j) {
      // h_j - h = (k_j - k) / 2:  (h_j - h) A <= d_j - c  and  (h - h_j) A <= d - c_j.
      if (k_[j] > k) {
        const double two_over_q = 2.0 * reciprocal(k_[j] - k);
        a_hi_ = std::min(a_hi_, (d_[j] - c) * two_over_q);
        a_lo_ = std::max(a_lo_, (c_[j] - d) * two_over_q);
      } else if (k_[j] < k) {
        const double two_over_q = 2.0 * reciprocal(k - k_[j]);
        a_lo_ = std::max(a_lo_, (c - d_[j]) * two_over_q);
        a_hi_ = std::min(a_hi_, (d - c_[j]) * two_over_q);
      }
    }
    if (h > 0.0) a_hi_ = std::min(a_hi_, (d - 1.0) * 2.0 * reciprocal(k - 1));
    k_[size_] = k;
    c_[size_] = c;
    d_[size_] = d;
    h_[size_] = h;
    ++size_;
  }
  // The real adds every pair of the windows leaves, [adds_lo, adds_hi] (empty: lo > hi, up to
  // rounding), a relaxation of F <= 0: the run's last-interval bound is not in it.
  double adds_lo() const { return a_lo_; }
  double adds_hi() const { return a_hi_; }

  // (3) at add a. With S empty: lower -inf, upper +inf. Branch-free selects (the extremes move
  // unpredictably between a few entries).
  Range at(double a) const {
    double lv = -std::numeric_limits<double>::infinity();
    double uv = std::numeric_limits<double>::infinity();
    uint32_t li = 0, ui = 0;
    for (uint32_t j = 0; j < size_; ++j) {
      const double lo = c_[j] - h_[j] * a, hi = d_[j] - h_[j] * a;
      li = lo > lv ? j : li;
      lv = lo > lv ? lo : lv;
      ui = hi < uv ? j : ui;
      uv = hi < uv ? hi : uv;
    }
    return {{lv, -h_[li], k_[li]}, {uv, -h_[ui], k_[ui]}};
  }

  // Entry j: its step and its real bounds on I at add a.
  uint32_t step(uint32_t j) const { return k_[j]; }
  double lower_at(uint32_t j, double a) const { return c_[j] - h_[j] * a; }
  double upper_at(uint32_t j, double a) const { return d_[j] - h_[j] * a; }

 private:
  static double reciprocal(uint32_t m) { return detail::reciprocal(m); }

  uint32_t size_ = 0;
  double a_lo_ = -std::numeric_limits<double>::infinity();
  double a_hi_ = std::numeric_limits<double>::infinity();
  uint32_t k_[kCapacity] = {};
  double c_[kCapacity] = {}, d_[kCapacity] = {}, h_[kCapacity] = {};
};

}  // namespace feedloop::stepgen
