// Compression of exact step times into runs (step_run.hpp) with a bounded step-time error
// (docs/protocol.md section 2).
//
// Each step i has an exact time T_i (real MCU ticks) and an allowed window
//   L_i = T_i - min(E, (T_i - T_{i-1}) / 2)  <=  t_i  <=  U_i = T_i + E
// where E is the maximum step-time error (default 5 us). Relative to the run's start P, step k
// of a run is at P + k I + k(k-1)/2 A with integers I (interval) and A (add); every interval
// I + (k-1) A must be >= 1.
//
// One pass over the steps, greedy run extension:
//  - a candidate (I, A) valid for steps 1..n is kept; a new step is accepted when the
//    candidate's next step (two integer additions) falls inside its window: the common case;
//  - otherwise a new candidate is fitted to a few of the run's windows (active_windows.hpp:
//    the run's first step, its middle, the step that was missed, and the steps that earlier
//    candidates missed): first the add from the curvature of the newest exact times (their
//    second difference), then, if that leaves no integer I, Newton steps on the convex F of
//    active_windows.hpp to the nearest adds that do; I continues the newest interval, within the
//    exact integer range. The candidate is then checked against every step of the run; the
//    step it misses worst joins the windows and the fit is repeated. F only grows as steps and
//    windows join, so every trial's tangent of F bounds the adds left for the rest of the run
//    (add_lo_, add_hi_): the search that ends a run mostly stops after its first trial, and a
//    run ends only when its windows prove that no (I, A) is left;
//  - when there is none, the run is emitted and the next one starts from its last step. Its first
//    candidate, when on_steps() has the next steps at hand, is the line through the mean
//    intervals at half and at all of the previous run's length (a run about as long as the last
//    one), clamped to the first step's window; otherwise the previous run's add.
// Every step of a run is checked against its window by the test that admitted it (a search's
// scan, or the fast path), as Klipper's check_line does; a run's searches check at most
// 16 steps per step of the run (plus 4096), so the work per step is bounded whatever the stream.
// A run whose end, expanded with the MCU step law, is not where the checks put it is counted in
// check_failures (never expected; tests assert zero) and sent as one-step runs that keep the
// bound instead.
#pragma once

#include <algorithm>  // std::min
#include <cstddef>
#include <cstdint>
#include <cstdlib>  // std::free
#include <memory>

#include "drivers/stepgen/active_windows.hpp"
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
  uint64_t searches = 0;  // steps the candidate did not take (a search followed)
  uint64_t trials = 0;    // adds tried exactly in those look-ups
  uint64_t scanned = 0;   // steps the searches checked their candidates against
  uint64_t check_failures = 0;
  uint64_t window_violations = 0;  // steps closer than one tick: error bound could not be met
};

class StepCompressor final : public StepSink {
 public:
  // Allocates the point buffers (max_run_count + 2 points). Not RT-safe.
  void configure(const StepCompressorParams& params, RunSink* sink);
  // Starts a new stream: the previous step is at last_step_clock (no pending run).
  void reset(int64_t last_step_clock, double last_step_target_ticks);

  // RT-safe (no allocation). The common case (the candidate run takes the step) is inline.
  void push(double target_ticks, int8_t direction) {
    const double prev = prev_target_;
    prev_target_ = target_ticks;
    if (n_ > 0 && direction == dir_ && n_ < params_.max_run_count && iv_ >= 1) {
      // The candidate's next step (two integer additions) against the window, in absolute
      // ticks: an integer clock is >= a real bound exactly when it is >= its ceiling.
      const auto next = static_cast<double>(pos_ + iv_);
      if (next >= target_ticks - std::min(params_.max_error_ticks, 0.5 * (target_ticks - prev)) &&
          next <= target_ticks + params_.max_error_ticks) {
        T_[++n_] = target_ticks;
        pos_ += iv_;
        iv_ += A_;
        return;
      }
    }
    push_slow(target_ticks, prev, direction);
  }
  // The same as push() for each step; the common case runs with the state in registers.
  void on_steps(const double* ticks, const int8_t* directions, size_t n) override {
    size_t i = 0;
    while (i < n) {
      i = extend_run(ticks, directions, i, n);
      if (i < n) {
        ahead_ = ticks + i + 1;
        ahead_n_ = n - i - 1;
        push(ticks[i], directions[i]);
        ahead_n_ = 0;
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
  // Starts a run whose first step is T_[1] (T_[0]: the step before it).
  void start_run_with_first_point();
  // A candidate valid for steps 1..n (n >= 2), fitted to the active windows and checked against
  // every step. False when there is none (or the run's check budget is spent).
  bool find_candidate(uint32_t n);
  // The exact integer range of I that the active windows leave at add a (empty: lo > hi), and
  // F(a) of active_windows.hpp with its derivative in a.
  struct Trial {
    int64_t i_lo, i_hi;
    double gap, gap_slope;  // I_min - I_max (> 0: no real I) and its derivative in a
    uint32_t k_lo, k_hi;    // the steps whose windows bound I
    double lo_value, hi_value;  // the real bounds on I from those windows
  };
  Trial trial(int64_t a, uint32_t n) const;
  // Same, real-valued only (no integer rounding): for the search over a.
  Trial gap_at(double a, uint32_t n) const;
  // A candidate (I, A) that the active windows leave (integer, every interval >= 1), searched
  // over the adds not yet ruled out. False when there is none.
  bool solve(uint32_t n, int64_t& I, int64_t& A);
  // 0 if (I, A) keeps steps 1..n in their windows, else the step it misses by the most mean
  // interval (active_windows.hpp (2)): the window most likely to bind; n if an interval < 1.
  uint32_t worst_violation(int64_t I, int64_t A, uint32_t n) const;
  void emit();
  void emit_single_steps();
  void push_slow(double target, double prev, int8_t direction);
  // Accepts steps i.. while the candidate run takes them (push()'s fast path, state kept in
  // locals); returns the index of the first step it does not take.
  size_t extend_run(const double* ticks, const int8_t* dirs, size_t i, size_t n) {
    uint32_t nn = n_;
    if (nn == 0) return i;
    const double E = params_.max_error_ticks;
    const uint32_t max_count = params_.max_run_count;
    const int8_t dir = dir_;
    const int64_t A = A_;
    double prev = prev_target_;
    int64_t pos = pos_, iv = iv_;
    double* T = T_.get();
    for (; i < n; ++i) {
      const double t = ticks[i];
      if (dirs[i] != dir || nn >= max_count || iv < 1) break;
      const auto next = static_cast<double>(pos + iv);
      if (next < t - std::min(E, 0.5 * (t - prev)) || next > t + E) break;
      T[++nn] = t;
      prev = t;
      pos += iv;
      iv += A;
    }
    n_ = nn;
    prev_target_ = prev;
    pos_ = pos;
    iv_ = iv;
    return i;
  }
  // Window of step k in absolute ticks (docs/protocol.md section 2).
  double window_lo(uint32_t k) const {
    return T_[k] - std::min(params_.max_error_ticks, 0.5 * (T_[k] - T_[k - 1]));
  }
  double window_hi(uint32_t k) const { return T_[k] + params_.max_error_ticks; }

  StepCompressorParams params_;
  RunSink* sink_ = nullptr;
  StepCompressorStats stats_;
  // Exact times of the current run's steps, 1-based; T_[0] is the step before the run's first.
  struct FreeDeleter {
    void operator()(void* p) const { std::free(p); }
  };
  std::unique_ptr<double[], FreeDeleter> T_;
  ActiveWindows active_;       // the windows the searches fit candidates to (active_windows.hpp)
  uint64_t scanned_ = 0;       // steps the current run's searches checked
  double prev_target_ = 0.0;   // exact time of the newest step pushed
  int64_t P_ = 0;              // clock of the last emitted step (run reference)
  uint32_t n_ = 0;             // accepted steps in the current run
  int8_t dir_ = 1;
  int64_t I_ = 0, A_ = 0;      // candidate
  int64_t pos_ = 0, iv_ = 0;   // candidate's clock of step n_ and its next interval
  int64_t last_add_ = 0;
  // Integer adds not yet ruled out for the current run (find_candidate narrows them).
  int64_t add_lo_ = 0, add_hi_ = -1;
  uint32_t last_count_ = 0;  // steps of the last run
  // Steps after the one being pushed, when on_steps() has them: a new run's first candidate
  // aims at where the run will likely end.
  const double* ahead_ = nullptr;
  size_t ahead_n_ = 0;
};

}  // namespace feedloop::stepgen
