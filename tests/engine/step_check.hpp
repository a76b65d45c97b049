// Test support: rebuilds every step time of a batch-mode run from the compressed QUEUE_STEPS
// bodies (RunDecoder + the MCU step law) and compares it with the exact step time computed
// independently from the closed-form joint motion (the JointSegments the planner emitted), by
// a bracketed root search (find_crossing) on the segment polynomials — no code of the step
// generator is used.
//
// Step convention (docs/protocol.md): a step in direction d crosses the threshold n + d/2 of
// s(t) = steps_per_mm * pos_mm(t). For the decoded step at time t the exact time is the nearest
// crossing of that threshold in direction d; its distance to t is the step-time error.
//
// Thread use: BatchOptions calls the taps from the thread that steps the joint concerned; all
// state here is per joint, so the two batch threads never share any of it.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <deque>
#include <limits>

#include "core/joint_segment.hpp"
#include "drivers/stepgen/run_codec.hpp"
#include "drivers/stepgen/step_batcher.hpp"
#include "engine/step_pipeline.hpp"
#include "planner/joint_output.hpp"

namespace feedloop::engine::testing {

struct JointCheckResult {
  uint64_t steps = 0;
  double max_error_us = 0.0;
  uint64_t not_found = 0;  // decoded steps with no crossing of their threshold nearby
  int64_t final_steps = 0;  // position after the last decoded step
};

class StepChecker final : public planner::JointSink, public stepgen::BatchSink {
 public:
  StepChecker(const std::array<double, kJoints>& steps_per_mm, double mcu_clock_hz, double max_error_us)
      : spm_(steps_per_mm), clock_hz_(mcu_clock_hz), window_s_(4.0 * max_error_us * 1e-6) {}

  void on_joint_segment(int joint, const JointSegment& seg) override {
    Joint& j = joints_[static_cast<size_t>(joint)];
    if (!j.started) {
      j.started = true;
      j.n = std::llround(seg.c0_mm * spm_[static_cast<size_t>(joint)]);
    }
    if (seg.duration_s > 0.0) j.segs.push_back(seg);
  }

  void on_batch(const stepgen::StepBatch& b) override {
    Joint& j = joints_[b.axis];
    stepgen::RunDecoder dec;
    if (!dec.begin(b.body, b.body_bytes)) {
      ++j.result.not_found;
      return;
    }
    int64_t clock = dec.first_clock();
    stepgen::StepRun r;
    while (!dec.done()) {
      if (!dec.next(r)) {
        ++j.result.not_found;
        return;
      }
      int64_t interval = r.interval_ticks;
      for (uint32_t k = 0; k < r.count; ++k) {  // next = last + interval; interval += add
        clock += interval;
        interval += r.add_ticks;
        check_step(j, b.axis, static_cast<double>(clock) / clock_hz_, r.direction);
      }
    }
  }

  JointCheckResult result(int joint) const {
    JointCheckResult r = joints_[static_cast<size_t>(joint)].result;
    r.final_steps = joints_[static_cast<size_t>(joint)].n;
    return r;
  }

 private:
  struct Joint {
    bool started = false;
    int64_t n = 0;
    std::deque<JointSegment> segs;
    JointCheckResult result;
  };

  // s(t) in steps: the segment that holds t (segments are contiguous and time-ordered).
  double steps_at(const Joint& j, size_t joint, double t) const {
    auto it = std::lower_bound(j.segs.begin(), j.segs.end(), t,
                               [](const JointSegment& s, double tt) { return s.end_s() < tt; });
    const JointSegment* seg = it == j.segs.end() ? &j.segs.back() : &*it;
    const double tc = std::clamp(t, seg->t0_s, seg->end_s());
    return seg->position_mm(tc) * spm_[joint];
  }

  void check_step(Joint& j, size_t joint, double t, int8_t d) {
    const double x = static_cast<double>(j.n) + 0.5 * d;
    j.n += d;
    ++j.result.steps;
    // Drop segments that end well before this step (steps come in time order).
    while (j.segs.size() > 1 && j.segs.front().end_s() < t - 2.0 * window_s_) j.segs.pop_front();
    if (j.segs.empty()) {
      ++j.result.not_found;
      return;
    }
    // f < 0 before the crossing, > 0 after it. Usually the crossing is bracketed by t +- E
    // (window / 4); otherwise find the sign change of f (from <= 0 to > 0) nearest to t in
    // [t - window, t + window] on a fine grid. Then narrow the bracket (find_crossing).
    auto f = [&](double tt) { return d * (steps_at(j, joint, tt) - x); };
    const double e = 0.25 * window_s_;
    if (f(t - e) <= 0.0 && f(t + e) > 0.0) {
      find_crossing(j, f, t - e, t + e, t);
      return;
    }
    constexpr int kGrid = 64;
    const double w = window_s_, h = 2.0 * w / kGrid;
    double best_lo = 0, best_hi = 0, best_dist = 1e300;
    double f_prev = f(t - w);
    for (int i = 1; i <= kGrid; ++i) {
      const double tb = t - w + h * i;
      const double fb = f(tb);
      if (f_prev <= 0.0 && fb > 0.0) {
        const double ta = tb - h;
        const double dist = (t < ta) ? ta - t : (t > tb ? t - tb : 0.0);
        if (dist < best_dist) best_dist = dist, best_lo = ta, best_hi = tb;
      }
      f_prev = fb;
    }
    if (best_dist > 1e299) {
      // A reversal right at the threshold: over it and back within one grid cell, anywhere in
      // the step's window (t - E, t + E). Find the extremum of f there (golden section; f is
      // unimodal there): f rises above 0 before a maximum (bracket [left end, argmax]) or leaves a
      // minimum <= 0 (bracket [argmin, right end]).
      const double left = t - std::max(2.0 * h, 1.25 * e), right = t + std::max(2.0 * h, 1.25 * e);
      auto extremum = [&](double sign) {
        double a = left, b = right;
        const double g = 0.5 * (std::sqrt(5.0) - 1.0);
        for (int it = 0; it < 60; ++it) {
          const double c1 = b - g * (b - a), c2 = a + g * (b - a);
          if (sign * f(c1) < sign * f(c2)) a = c1; else b = c2;
        }
        return 0.5 * (a + b);
      };
      const double tmax = extremum(1.0), tmin = extremum(-1.0);
      if (f(left) <= 0.0 && f(tmax) > 0.0) {
        best_lo = left, best_hi = tmax;
      } else if (f(tmin) <= 0.0 && f(right) > 0.0) {
        best_lo = tmin, best_hi = right;
      } else {
        ++j.result.not_found;
        return;
      }
    }
    find_crossing(j, f, best_lo, best_hi, t);
  }

  // The crossing in [lo, hi] (f(lo) <= 0 < f(hi)) to within 1 ps, or 2 ulp of the time where
  // that is coarser (0.9 ps at an hour): the Illinois form of regula falsi, which keeps the bracket
  // as bisection does and needs a few evaluations where f is near linear (a step's window of a
  // smooth motion) instead of 32 halvings; a point that would not shrink the bracket is replaced
  // by its middle. (Bisection took 152 s of the corpus test's CPU, most of it here.)
  template <class F>
  static void find_crossing(Joint& j, const F& f, double lo, double hi, double t) {
    const double tol = std::max(1e-12, 4.0 * std::numeric_limits<double>::epsilon() * std::fabs(t));
    double f_lo = f(lo), f_hi = f(hi);
    int kept = 0;  // the end kept by the last two steps: -1 lo, +1 hi
    for (int it = 0; it < 200 && hi - lo > tol; ++it) {
      double mid = f_hi > f_lo ? lo - f_lo * (hi - lo) / (f_hi - f_lo) : 0.5 * (lo + hi);
      if (!(mid > lo && mid < hi)) mid = 0.5 * (lo + hi);
      if (!(mid > lo && mid < hi)) break;  // no double between them
      const double f_mid = f(mid);
      if (f_mid > 0.0) {
        hi = mid, f_hi = f_mid;
        if (kept == -1) f_lo *= 0.5;  // lo stayed twice: weigh it less (Illinois)
        kept = -1;
      } else {
        lo = mid, f_lo = f_mid;
        if (kept == 1) f_hi *= 0.5;
        kept = 1;
      }
    }
    const double err_us = std::fabs(0.5 * (lo + hi) - t) * 1e6;
    j.result.max_error_us = std::max(j.result.max_error_us, err_us);
  }

  std::array<double, kJoints> spm_;
  double clock_hz_;
  double window_s_;
  std::array<Joint, kJoints> joints_;
};

}  // namespace feedloop::engine::testing
