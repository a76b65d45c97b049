// Greedy run compression in one pass, candidates fitted to a few active windows and checked
// against every step: see step_compressor.hpp and active_windows.hpp.
#include "drivers/stepgen/step_compressor.hpp"

#include <algorithm>  // std::min, std::max, std::clamp
#include <cmath>      // std::abs
#include <cstdlib>    // malloc
#include <utility>    // std::pair

namespace feedloop::stepgen {

namespace {
constexpr int64_t kMaxAdd = INT32_MAX;  // add_ticks is 32-bit on the wire
constexpr int kNewtonSteps = 8;         // pieces of F crossed on the way to a feasible slope
constexpr int kTrials = 8;              // integer adds tried after the first
constexpr double kGapTol = 1e-7;        // ticks: F(s) this small counts as touching (doubles)
constexpr double kRootSlack = 1e-6;     // adds: a tangent's root, widened for rounding
constexpr double kTieTol = 1e-3;        // intervals: real bounds this close may round either way
// A run's searches check at most this many steps per step of the run (plus the base): bounded
// work per step whatever the stream (a run whose searches would exceed it ends there).
constexpr uint64_t kScanPerStep = 16;
constexpr uint64_t kScanBase = 4096;
using detail::ceil_i;
using detail::floor_i;
using detail::round_i;
inline int64_t tri(int64_t k) {
  return k * (k - 1) / 2;
}
}  // namespace

void StepCompressor::configure(const StepCompressorParams& params, RunSink* sink) {
  params_ = params;
  if (params_.max_run_count < 1) params_.max_run_count = 1;
  sink_ = sink;
  // Default-initialised (not zeroed): points are written before they are read, and pages a run
  // never reaches are never touched, so resident memory follows the longest run, not the limit.
  const size_t cap = static_cast<size_t>(params_.max_run_count) + 2;
  T_.reset(static_cast<double*>(std::malloc(cap * sizeof(double))));
  stats_ = {};
  reset(0, 0.0);
}

void StepCompressor::reset(int64_t last_step_clock, double last_step_target_ticks) {
  P_ = last_step_clock;
  prev_target_ = last_step_target_ticks;
  n_ = 0;
  active_.clear();
}

void StepCompressor::push_slow(double target, double prev, int8_t direction) {
  if (n_ > 0 && direction != dir_) emit();
  dir_ = direction;
  if (n_ == 0) {
    T_[0] = prev;
    T_[1] = target;
    start_run_with_first_point();
    return;
  }
  const uint32_t k = n_ + 1;
  T_[k] = target;
  if (k <= params_.max_run_count && find_candidate(k)) {
    const int64_t kk = k;
    pos_ = P_ + kk * I_ + A_ * tri(kk);
    iv_ = I_ + kk * A_;
    n_ = k;
    return;
  }
  emit();
  T_[0] = prev;
  T_[1] = target;
  start_run_with_first_point();
}

void StepCompressor::start_run_with_first_point() {
  const double p = static_cast<double>(P_);
  const int64_t lo_i = std::max<int64_t>(1, ceil_i(window_lo(1) - p)),
                hi_i = floor_i(window_hi(1) - p);
  int64_t I = round_i(T_[1] - p);
  if (lo_i <= hi_i) {
    I = std::clamp<int64_t>(I, lo_i, hi_i);
  } else {
    I = std::max<int64_t>(1, I);
    ++stats_.window_violations;
  }
  I_ = I;
  A_ = last_add_;  // the previous run's curvature: often right for the next steps too
  // With the next steps at hand: the mean-interval line (active_windows.hpp (1)) through the mean
  // intervals at half and at all of the last run's length, the run these steps are likely to
  // end on (a candidate only: the searches decide).
  const size_t m = std::min<size_t>(std::clamp<uint32_t>(last_count_, 4, 256), ahead_n_ + 1);
  if (m >= 4 && lo_i <= hi_i) {
    const size_t k1 = m / 2, k2 = m;
    const double m1 = (k1 == 1 ? T_[1] : ahead_[k1 - 2]) - p, m2 = ahead_[k2 - 2] - p;
    const double c1 = m1 * detail::reciprocal(static_cast<uint32_t>(k1));
    const double c2 = m2 * detail::reciprocal(static_cast<uint32_t>(k2));
    const double a = 2.0 * (c2 - c1) * detail::reciprocal(static_cast<uint32_t>(k2 - k1));
    if (std::abs(a) < 1e9) {
      A_ = round_i(a);
      I_ = std::clamp<int64_t>(
          round_i(c1 - 0.5 * static_cast<double>(k1 - 1) * static_cast<double>(A_)), lo_i, hi_i);
      I = I_;
    }
  }
  pos_ = P_ + I;
  iv_ = I + A_;
  n_ = 1;
  active_.clear();
  scanned_ = 0;
  add_lo_ = -kMaxAdd;
  add_hi_ = kMaxAdd;
}

StepCompressor::Trial StepCompressor::gap_at(double a, uint32_t n) const {
  const ActiveWindows::Range r = active_.at(a);
  // I >= 1 and the last interval I + (n-1) A >= 1 (intervals are linear in k).
  double lower = r.lower.value, d_lower = r.lower.slope;
  if (lower < 1.0) lower = 1.0, d_lower = 0.0;
  const double nm1 = n - 1.0, last = 1.0 - nm1 * a;
  if (last > lower) lower = last, d_lower = -nm1;
  return {0,         -1,        lower - r.upper.value, d_lower - r.upper.slope,
          r.lower.k, r.upper.k, r.lower.value,         r.upper.value};
}

StepCompressor::Trial StepCompressor::trial(int64_t a, uint32_t n) const {
  const auto ad = static_cast<double>(a);
  Trial t = gap_at(ad, n);
  // Integer bounds settled by the exact test the fast path uses: the integer clock
  // P + k I + t_k a against the window's real bound.
  auto clock = [&](int64_t k, int64_t i) { return static_cast<double>(P_ + k * i + tri(k) * a); };
  auto settle_lo = [&](int64_t k, double real) {
    const double lo = window_lo(static_cast<uint32_t>(k));
    int64_t i = ceil_i(std::clamp(real, -4e18, 4e18));
    while (clock(k, i - 1) >= lo) --i;
    while (clock(k, i) < lo) ++i;
    return i;
  };
  auto settle_hi = [&](int64_t k, double real) {
    const double hi = window_hi(static_cast<uint32_t>(k));
    int64_t i = floor_i(std::clamp(real, -4e18, 4e18));
    while (clock(k, i + 1) <= hi) ++i;
    while (clock(k, i) > hi) --i;
    return i;
  };
  int64_t i_lo = settle_lo(t.k_lo, t.lo_value), i_hi = settle_hi(t.k_hi, t.hi_value);
  // Another window whose real bound is within rounding of the settled integer may round past it
  // (none can when the extreme itself is not that close).
  if (t.lo_value > static_cast<double>(i_lo) - kTieTol) {
    for (uint32_t j = 0; j < active_.size(); ++j) {
      const uint32_t k = active_.step(j);
      if (k != t.k_lo && active_.lower_at(j, ad) > static_cast<double>(i_lo) - kTieTol)
        i_lo = std::max(i_lo, settle_lo(k, active_.lower_at(j, ad)));
    }
  }
  if (t.hi_value < static_cast<double>(i_hi) + kTieTol) {
    for (uint32_t j = 0; j < active_.size(); ++j) {
      const uint32_t k = active_.step(j);
      if (k != t.k_hi && active_.upper_at(j, ad) < static_cast<double>(i_hi) + kTieTol)
        i_hi = std::min(i_hi, settle_hi(k, active_.upper_at(j, ad)));
    }
  }
  t.i_lo = std::max({i_lo, int64_t{1}, 1 - static_cast<int64_t>(n - 1) * a});
  t.i_hi = i_hi;
  return t;
}

bool StepCompressor::find_candidate(uint32_t n) {
  ++stats_.searches;
  if (add_lo_ > add_hi_) return false;  // an earlier search left no add for this run
  const double p = static_cast<double>(P_);
  auto add_window = [&](uint32_t k) { active_.add(k, window_lo(k) - p, window_hi(k) - p); };
  // The run's first step and the step that the candidate missed; then every step the new
  // candidate misses, until one takes them all or the windows leave none.
  if (active_.size() == 0 && n > 1) {
    add_window(1);
    if (n > 3) add_window(n / 2);
  }
  if (active_.full()) return false;
  add_window(n);
  for (;;) {
    int64_t I = 0, A = 0;
    if (!solve(n, I, A)) return false;
    if (scanned_ > kScanPerStep * n + kScanBase) return false;  // bounded work per step
    const uint32_t v = worst_violation(I, A, n);
    const uint32_t checked = n;
    scanned_ += checked;
    stats_.scanned += checked;
    if (v == 0) {
      I_ = I;
      A_ = A;
      return true;
    }
    // A step already in S: the exact settle disagrees with the check (rounding); end the run.
    if (active_.full() || active_.contains(v)) return false;
    add_window(v);
  }
}

bool StepCompressor::solve(uint32_t n, int64_t& I_out, int64_t& A_out) {
  // The integer adds inside the real ones that every pair of windows leaves (widened for
  // rounding): none means no run.
  {
    const double lo = active_.adds_lo(), hi = active_.adds_hi();
    const double slack = kRootSlack * (1.0 + std::abs(lo) + std::abs(hi));
    if (lo > -kMaxAdd) add_lo_ = std::max(add_lo_, ceil_i(lo - slack));
    if (hi < kMaxAdd) add_hi_ = std::min(add_hi_, floor_i(hi + slack));
    if (add_lo_ > add_hi_) return false;
  }
  const double d_n = T_[n] - T_[n - 1], nm1 = n - 1.0;
  auto accept = [&](int64_t a, const Trial& t) {
    // The I whose last interval is the newest exact one: the next steps continue it.
    const double i_pref = d_n - nm1 * static_cast<double>(a);
    I_out = std::clamp<int64_t>(round_i(std::clamp(i_pref, -4e18, 4e18)), t.i_lo, t.i_hi);
    A_out = a;
    return true;
  };
  // F is convex and only grows as steps and windows join, so its tangent at any trial bounds the
  // adds that can still work, now and for the rest of the run: none lies past the tangent's root
  // on the side where it rises. The bounds make later searches short (the one that ends the run
  // mostly finds no add left after one trial). False when no add is left.
  auto bound = [&](double x, const Trial& g) {
    if (g.gap_slope != 0.0) {
      const double root = std::clamp(x - g.gap / g.gap_slope, -2.0 * kMaxAdd, 2.0 * kMaxAdd);
      if (g.gap_slope > 0.0)
        add_hi_ = std::min(add_hi_, floor_i(root + kRootSlack));
      else
        add_lo_ = std::max(add_lo_, ceil_i(root - kRootSlack));
    } else if (g.gap > kGapTol) {
      add_hi_ = add_lo_ - 1;  // F is flat and above zero: its minimum
    }
    return add_lo_ <= add_hi_;
  };
  // First trial: the add from the curvature of the newest exact times (their second
  // difference): the run the steps are about to follow.
  const double a_pref = d_n - (T_[n - 1] - T_[n - 2]);
  int64_t a = std::clamp(
      round_i(std::clamp(a_pref, -static_cast<double>(kMaxAdd), static_cast<double>(kMaxAdd))),
      add_lo_, add_hi_);
  ++stats_.trials;
  Trial t = trial(a, n);
  if (t.i_lo <= t.i_hi) return accept(a, t);
  if (!bound(static_cast<double>(a), t)) return false;
  int step;
  if (t.gap > 0.0) {
    // No real I at this add: Newton on the convex, piecewise linear F to the near end of the
    // feasible adds. Each step lands on the root of F's current piece; F is above every piece,
    // so no add passed over is feasible (bound() says so). A derivative that changes sign means
    // min F > 0.
    step = t.gap_slope > 0.0 ? -1 : 1;
    double x = static_cast<double>(a);
    Trial g = t;
    for (int it = 0; g.gap > kGapTol; ++it) {
      if (it == kNewtonSteps) return false;
      x -= g.gap / g.gap_slope;
      if (!(x > -static_cast<double>(kMaxAdd) && x < static_cast<double>(kMaxAdd))) return false;
      const Trial h = gap_at(x, n);
      if (h.gap > kGapTol && (h.gap_slope == 0.0 || (h.gap_slope > 0.0) != (g.gap_slope > 0.0))) {
        add_hi_ = add_lo_ - 1;
        return false;
      }
      if (!bound(x, h)) return false;
      g = h;
    }
    a = step > 0 ? ceil_i(x - 1e-9) : floor_i(x + 1e-9);
  } else {
    // Real I exist but no integer one (a thin part of the polygon): walk towards where it widens.
    step = t.gap_slope > 0.0 ? -1 : 1;
    a += step;
  }
  for (int i = 0; i <= kTrials && a >= add_lo_ && a <= add_hi_; ++i, a += step) {
    ++stats_.trials;
    t = trial(a, n);
    if (t.i_lo <= t.i_hi) return accept(a, t);
    // An add that fails now fails for the rest of the run.
    if (a == add_lo_)
      ++add_lo_;
    else if (a == add_hi_)
      --add_hi_;
    if (!bound(static_cast<double>(a), t)) return false;
    if (i > 0 && t.gap > kGapTol) break;  // past the far end
  }
  return false;
}

uint32_t StepCompressor::worst_violation(int64_t I, int64_t A, uint32_t n) const {
  if (I + static_cast<int64_t>(n - 1) * A < 1 || I < 1) return n;  // intervals are linear in k
  int64_t clock = P_, iv = I;
  double worst = 0.0;  // the largest miss of the mean interval, (2): ticks over k
  uint32_t worst_k = 0;
  auto check = [&](uint32_t k, double over_k) {
    clock += iv;
    iv += A;
    const auto c = static_cast<double>(clock);
    const double miss = std::max(window_lo(k) - c, c - window_hi(k)) * over_k;
    worst_k = miss > worst ? k : worst_k;
    worst = miss > worst ? miss : worst;
  };
  const uint32_t n_table = std::min<uint32_t>(n, detail::kReciprocals.size() - 1);
  for (uint32_t k = 1; k <= n_table; ++k) check(k, detail::kReciprocals[k]);
  for (uint32_t k = n_table + 1; k <= n; ++k) check(k, 1.0 / static_cast<double>(k));
  return worst_k;
}

void StepCompressor::emit() {
  if (n_ == 0) return;
  StepRun run;
  run.interval_ticks = I_;
  run.add_ticks = static_cast<int32_t>(A_);
  run.count = n_;
  run.direction = dir_;
  // Every step of the run was checked against its window by the test that admitted it (the
  // search's scan of steps 1..n for the candidate it chose, the fast path for each later step);
  // the run's end, expanded with the MCU step law, must be where those checks put it.
  if (run_end_clock(P_, run) != pos_) {
    ++stats_.check_failures;
    emit_single_steps();
    return;
  }
  if (sink_ != nullptr) sink_->on_run(P_, run);
  stats_.runs += 1;
  stats_.steps += n_;
  P_ = pos_;
  last_add_ = A_;
  last_count_ = n_;
  n_ = 0;
}

// The fallback for a run that failed its check (never expected): each step alone, on its exact
// time rounded into its window, one tick after the previous at least.
void StepCompressor::emit_single_steps() {
  for (uint32_t k = 1; k <= n_; ++k) {
    const int64_t lo = ceil_i(window_lo(k)), hi = floor_i(window_hi(k));
    const int64_t clock = std::max(P_ + 1, std::clamp(round_i(T_[k]), lo, std::max(lo, hi)));
    if (clock > hi) ++stats_.window_violations;
    StepRun run;
    run.interval_ticks = clock - P_;
    run.count = 1;
    run.direction = dir_;
    if (sink_ != nullptr) sink_->on_run(P_, run);
    stats_.runs += 1;
    stats_.steps += 1;
    P_ = clock;
  }
  last_add_ = 0;
  n_ = 0;
}

void StepCompressor::flush() { emit(); }

}  // namespace feedloop::stepgen
