// Compression of exact step times into runs (step_run.hpp) with a bounded step-time error.
//
// Each step i has an exact time T_i (real MCU ticks) and an allowed window
//   L_i = T_i - min(E, (T_i - T_{i-1}) / 2)  <=  t_i  <=  U_i = T_i + E
// where E is the maximum step-time error (default 5 us). Relative to the run's start P, step k
// of a run is at P + k I + k(k-1)/2 A with integers I (interval) and A (add). The set of (I, A)
// that keeps steps 1..n inside their windows (and every interval I + (k-1) A >= 1) is a convex
// polygon: the intersection of strips  L_k - P <= k I + k(k-1)/2 A <= U_k - P.
//
// Greedy run extension, O(1) amortised per step:
//  - keep one integer candidate (I, A) valid for steps 1..n; a new step is accepted if the
//    candidate's next step (two integer additions) falls inside its window;
//  - only when it does not, look for another integer point near the centre of the polygon of an
//    active set of strips (cutting planes: a candidate is verified exactly in integer arithmetic
//    against all steps and the first step it violates joins the active set);
//  - when none exists, emit the run and start the next one from its last step.
// Before a run is handed to the sink it is checked again by expanding it with the MCU step law
// (as Klipper's check_line does); a run that fails the check is counted in `check_failures()`
// (never expected; tests assert zero).
#pragma once

#include <algorithm>  // std::min
#include <cstddef>
#include <cstdint>
#include <cstdlib>  // std::free
#include <memory>

#include "drivers/stepgen/step_generator.hpp"
#include "drivers/stepgen/step_run.hpp"

namespace feedloop::stepgen {

namespace detail {
// Inline rounding (libm's ceil/floor/llround are calls without SSE4.1); |x| < 2^62.
inline int64_t ceil_i(double x) {
  const auto t = static_cast<int64_t>(x);
  return static_cast<double>(t) < x ? t + 1 : t;
}
inline int64_t floor_i(double x) {
  const auto t = static_cast<int64_t>(x);
  return static_cast<double>(t) > x ? t - 1 : t;
}
inline int64_t round_i(double x) { return floor_i(x + 0.5); }
}  // namespace detail

struct StepCompressorParams {
  double max_error_ticks = 100.0;  // 5 us at 20 MHz
  uint32_t max_run_count = 65535;
};

struct StepCompressorStats {
  uint64_t steps = 0;
  uint64_t runs = 0;
  uint64_t candidate_searches = 0;
  uint64_t clips = 0, clip_vertices = 0, verifies = 0, add_tries = 0;  // cost counters of the searches
  uint64_t trend_tries = 0, trend_hits = 0;  // cheap candidates tried before a polygon search
  uint64_t check_failures = 0;
  uint64_t window_violations = 0;  // steps closer than one tick: error bound could not be met
};

class StepCompressor final : public StepSink {
 public:
  // Allocates the point buffer (max_run_count + 1 points). Not RT-safe.
  void configure(const StepCompressorParams& params, RunSink* sink);
  // Starts a new stream: the previous step is at last_step_clock (no pending run).
  void reset(int64_t last_step_clock, double last_step_target_ticks);

  // RT-safe (no allocation). The common case (the candidate run takes the step) is inline.
  void push(double target_ticks, int8_t direction) {
    const double lo = target_ticks - std::min(params_.max_error_ticks, 0.5 * (target_ticks - prev_target_));
    prev_target_ = target_ticks;
    if (n_ > 0 && direction == dir_ && n_ < params_.max_run_count) {
      const uint32_t k = n_ + 1;
      set_point(k, target_ticks, lo);
      const int64_t rel = pos_ + iv_ - P_;  // the candidate's next step: two integer additions
      if (iv_ >= 1 && rel >= lo_i_[k] && rel <= hi_i_[k]) {
        pos_ += iv_;
        iv_ += A_;
        n_ = k;
        return;
      }
    }
    push_slow(target_ticks, lo, direction);
  }
  // The same as push() for each step; the common case runs with the state in registers.
  void on_steps(const double* ticks, const int8_t* directions, size_t n) override {
    size_t i = 0;
    while (i < n) {
      i = extend_run(ticks, directions, i, n);
      if (i < n) {
        push(ticks[i], directions[i]);
        ++i;
      }
    }
  }
  // Emits the pending run (end of a batch or of the stream).
  void flush();
  // Emits the pending run if its first step is at or before deadline_clock: a run stays open
  // while later steps can extend it, so the caller (the engine) must close runs whose steps are
  // about to be due on the MCU. RT-safe.
  void flush_if_due(int64_t deadline_clock) {
    if (n_ > 0 && P_ + I_ <= deadline_clock) emit();
  }

  int64_t last_emitted_clock() const { return P_; }
  const StepCompressorStats& stats() const { return stats_; }
  const StepCompressorParams& params() const { return params_; }

 private:
  struct Vertex {
    double i, a;
  };
  void start_run_with_first_point();
  bool search_candidate(uint32_t n);
  bool try_trend(uint32_t n);
  // 0 if (I, A) keeps steps 1..n in their windows, else the first step that it violates.
  uint32_t first_violation(int64_t I, int64_t A, uint32_t n) const;
  void clip_strip(uint32_t k);
  void clip(double ni, double na, double c);  // keep ni*I + na*A <= c
  void emit();
  // Window of step k relative to P, rounded inwards to whole ticks (model times are integers).
  double lower(uint32_t k) const { return static_cast<double>(lo_i_[k]); }
  double upper(uint32_t k) const { return static_cast<double>(hi_i_[k]); }
  void set_point(uint32_t k, double target, double lo_abs) {
    T_[k] = target;
    const double p = static_cast<double>(P_);
    lo_i_[k] = detail::ceil_i(lo_abs - p);
    hi_i_[k] = detail::floor_i(target + params_.max_error_ticks - p);
  }
  void push_slow(double target, double lo, int8_t direction);
  // Accepts steps i.. while the candidate run takes them (push()'s fast path, state kept in
  // locals); returns the index of the first step it does not take.
  size_t extend_run(const double* ticks, const int8_t* dirs, size_t i, size_t n) {
    uint32_t nn = n_;
    if (nn == 0) return i;
    const double E = params_.max_error_ticks, p = static_cast<double>(P_);
    const uint32_t max_count = params_.max_run_count;
    const int8_t dir = dir_;
    const int64_t A = A_, P = P_;
    double prev = prev_target_;
    int64_t pos = pos_, iv = iv_;
    double* T = T_.get();
    int64_t* lo_i = lo_i_.get();
    int64_t* hi_i = hi_i_.get();
    for (; i < n; ++i) {
      const double t = ticks[i];
      if (dirs[i] != dir || nn >= max_count || iv < 1) break;
      const uint32_t k = nn + 1;
      const int64_t lo = detail::ceil_i(t - std::min(E, 0.5 * (t - prev)) - p);
      const int64_t hi = detail::floor_i(t + E - p);
      const int64_t rel = pos + iv - P;
      if (rel < lo || rel > hi) break;
      T[k] = t;
      lo_i[k] = lo;
      hi_i[k] = hi;
      prev = t;
      pos += iv;
      iv += A;
      nn = k;
    }
    n_ = nn;
    prev_target_ = prev;
    pos_ = pos;
    iv_ = iv;
    return i;
  }

  StepCompressorParams params_;
  RunSink* sink_ = nullptr;
  StepCompressorStats stats_;
  // Points of the current run, 1-based (index 0 unused): exact targets T (absolute ticks) and
  // the integer window [lo_i, hi_i] relative to P.
  struct FreeDeleter {
    void operator()(void* p) const { std::free(p); }
  };
  std::unique_ptr<double[], FreeDeleter> T_;
  std::unique_ptr<int64_t[], FreeDeleter> lo_i_, hi_i_;
  double prev_target_ = 0.0;   // exact time of the step before the newest point
  int64_t P_ = 0;              // clock of the last emitted step (run reference)
  uint32_t n_ = 0;             // accepted steps in the current run
  int8_t dir_ = 1;
  int64_t I_ = 0, A_ = 0;      // candidate
  int64_t pos_ = 0, iv_ = 0;   // candidate's clock of step n_ and its next interval
  int64_t last_add_ = 0;
  // Cutting-plane polygon (two buffers swapped by clip()).
  static constexpr int kMaxVerts = 64;
  Vertex buf_a_[kMaxVerts];
  Vertex buf_b_[kMaxVerts];
  Vertex* poly_ = buf_a_;
  Vertex* tmp_ = buf_b_;
  bool poly_init_ = false;
  int nv_ = 0;
  bool poly_overflow_ = false;
};

}  // namespace feedloop::stepgen
