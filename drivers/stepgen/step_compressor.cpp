// Greedy run compression with a lazily clipped feasible polygon: see step_compressor.hpp.
#include "drivers/stepgen/step_compressor.hpp"

#include <algorithm>  // std::min, std::max, std::clamp
#include <cmath>      // ceil, floor, llround
#include <cstdlib>    // malloc

namespace feedloop::stepgen {

namespace {
constexpr double kAddBound = 1e7;  // |A| box before the second step bounds it (ticks)
constexpr double kEps = 1e-7;      // slack for the floating polygon; runs are verified exactly
constexpr int kAddTries = 24;      // integer adds tried around the polygon's centre
constexpr int kMaxCuts = 12;       // cutting-plane rounds per search
using detail::ceil_i;
using detail::floor_i;
using detail::round_i;
}  // namespace

void StepCompressor::configure(const StepCompressorParams& params, RunSink* sink) {
  params_ = params;
  if (params_.max_run_count < 1) params_.max_run_count = 1;
  sink_ = sink;
  // Default-initialised (not zeroed): points are written before they are read, and pages a run
  // never reaches are never touched, so resident memory follows the longest run, not the limit.
  const size_t cap = static_cast<size_t>(params_.max_run_count) + 2;
  T_.reset(static_cast<double*>(std::malloc(cap * sizeof(double))));
  lo_i_.reset(static_cast<int64_t*>(std::malloc(cap * sizeof(int64_t))));
  hi_i_.reset(static_cast<int64_t*>(std::malloc(cap * sizeof(int64_t))));
  stats_ = {};
  reset(0, 0.0);
}

void StepCompressor::reset(int64_t last_step_clock, double last_step_target_ticks) {
  P_ = last_step_clock;
  prev_target_ = last_step_target_ticks;
  n_ = 0;
  poly_init_ = false;
}

void StepCompressor::push_slow(double target, double lo, int8_t direction) {
  if (n_ > 0 && direction != dir_) emit();
  dir_ = direction;
  const uint32_t k = n_ + 1;
  set_point(k, target, lo);
  if (n_ == 0) {
    start_run_with_first_point();
    return;
  }
  if (k <= params_.max_run_count && (try_trend(k) || search_candidate(k))) {
    const int64_t kk = k;
    pos_ = P_ + kk * I_ + A_ * (kk * (kk - 1) / 2);
    iv_ = I_ + kk * A_;
    n_ = k;
    return;
  }
  emit();
  set_point(1, target, lo);
  start_run_with_first_point();
}

void StepCompressor::start_run_with_first_point() {
  const double lo_i = std::max(1.0, lower(1)), hi_i = upper(1);
  int64_t I = round_i(T_[1] - static_cast<double>(P_));
  if (lo_i <= hi_i) {
    I = std::clamp<int64_t>(I, static_cast<int64_t>(lo_i), static_cast<int64_t>(hi_i));
  } else {
    I = std::max<int64_t>(1, I);
    ++stats_.window_violations;
  }
  I_ = I;
  A_ = last_add_;
  pos_ = P_ + I;
  iv_ = I + A_;
  n_ = 1;
  poly_init_ = false;
}

void StepCompressor::clip(double ni, double na, double c) {
  if (nv_ == 0) return;
  ++stats_.clips;
  stats_.clip_vertices += nv_;
  int m = 0;
  for (int j = 0; j < nv_; ++j) {
    const Vertex& p = poly_[j];
    const Vertex& q = poly_[j + 1 == nv_ ? 0 : j + 1];
    const double dp = ni * p.i + na * p.a - c;
    const double dq = ni * q.i + na * q.a - c;
    if (m + 2 > kMaxVerts) {
      poly_overflow_ = true;
      nv_ = 0;
      return;
    }
    if (dp <= 0.0) tmp_[m++] = p;
    if ((dp < 0.0 && dq > 0.0) || (dp > 0.0 && dq < 0.0)) {
      const double t = dp / (dp - dq);
      tmp_[m++] = {p.i + t * (q.i - p.i), p.a + t * (q.a - p.a)};
    }
  }
  nv_ = m;
  std::swap(poly_, tmp_);
}

uint32_t StepCompressor::first_violation(int64_t I, int64_t A, uint32_t n) const {
  // Newest steps first: a candidate that fails usually fails there (the run drifts away from
  // the targets as it grows), so failures are found in a few steps; a pass scans all n.
  const int64_t* lo = lo_i_.get();
  const int64_t* hi = hi_i_.get();
  if (I + static_cast<int64_t>(n - 1) * A < 1 || I < 1) return n;  // intervals are linear in k
  for (uint32_t k = n; k >= 1; --k) {
    const int64_t kk = k;
    const int64_t rel = kk * I + A * (kk * (kk - 1) / 2);
    if (rel < lo[k] || rel > hi[k]) return k;
  }
  return 0;
}

void StepCompressor::clip_strip(uint32_t k) {
  const double kk = k, tk = 0.5 * kk * (kk - 1.0);
  clip(kk, tk, upper(k));
  clip(-kk, -tk, -lower(k));
}

// Cheap first attempt without the polygon: the run that passes through the newest step's exact
// time with the newest interval (its add from the last two steps), verified exactly.
bool StepCompressor::try_trend(uint32_t n) {
  if (n < 3) return false;
  ++stats_.trend_tries;
  const double nd = n, p = static_cast<double>(P_);
  const double tn = T_[n] - p, d = T_[n] - T_[n - 1];
  const double tri = 0.5 * nd * (nd - 1.0);
  const int64_t a = round_i((nd * d - tn) / tri);
  const int64_t i = round_i((tn - tri * static_cast<double>(a)) / nd);
  if (first_violation(i, a, n) != 0) return false;
  ++stats_.trend_hits;
  I_ = i;
  A_ = a;
  return true;
}

// Cutting planes: the polygon holds the box, the strips of the steps that rejected a candidate
// (and the first and newest steps), and the interval-positivity constraints; all of them stay
// valid for the rest of the run, so the polygon only ever gets clipped, never rebuilt. A
// candidate from it is checked exactly against all n steps; the first step it violates is
// clipped in next.
bool StepCompressor::search_candidate(uint32_t n) {
  ++stats_.candidate_searches;
  if (!poly_init_) {
    const double lo_i = std::max(1.0, lower(1)), hi_i = upper(1);
    if (lo_i > hi_i) return false;
    poly_[0] = {lo_i, -kAddBound};
    poly_[1] = {hi_i, -kAddBound};
    poly_[2] = {hi_i, kAddBound};
    poly_[3] = {lo_i, kAddBound};
    nv_ = 4;
    poly_init_ = true;
  }
  clip_strip(n);
  // Interval positivity (I + (k-1) A >= 1) is clipped in only once a candidate violates it;
  // it almost never binds (intervals are thousands of ticks).
  uint32_t last_cut = n;
  bool positivity_clipped = false;
  for (int iter = 0; iter < kMaxCuts; ++iter) {
    if (nv_ < 3) return false;
    double amin = poly_[0].a, amax = poly_[0].a, ca = 0.0;
    for (int j = 0; j < nv_; ++j) {
      amin = std::min(amin, poly_[j].a);
      amax = std::max(amax, poly_[j].a);
      ca += poly_[j].a;
    }
    ca /= nv_;
    const int64_t alo = ceil_i(amin - kEps), ahi = floor_i(amax + kEps);
    if (alo > ahi) return false;
    // Preferred add: the one whose run follows the newest steps' local interval
    // (m_n - m_{n-1} = I + (n-1) A = T_n - T_{n-1} together with m_n = T_n), so the run
    // extrapolates the trend; the polygon's centroid when that is outside the polygon.
    double a_pref = ca;
    if (n >= 3) {
      const uint32_t j = n - 1;  // the newest two steps (longer baselines did worse)
      const double nd = n, jd = j;
      const double tn = T_[n] - static_cast<double>(P_), tj = T_[j] - static_cast<double>(P_);
      const double a_trend = (jd * tn - nd * tj) / (0.5 * jd * nd * (nd - jd));
      if (a_trend >= amin && a_trend <= amax) a_pref = a_trend;
    }
    const int64_t a0 = std::clamp<int64_t>(round_i(a_pref), alo, ahi);
    uint32_t cut = 0;
    bool any = false;
    for (int t = 0; t < kAddTries && cut == 0; ++t) {
      const int64_t a = (t & 1) ? a0 + (t + 1) / 2 : a0 - t / 2;
      if (a < alo || a > ahi) {
        if (a0 + (t + 2) / 2 > ahi && a0 - (t + 1) / 2 < alo) break;
        continue;
      }
      ++stats_.add_tries;
      // Range of I on the line A = a.
      const double ad = static_cast<double>(a);
      double imin = 1e300, imax = -1e300;
      for (int j = 0; j < nv_; ++j) {
        const Vertex& p = poly_[j];
        const Vertex& q = poly_[j + 1 == nv_ ? 0 : j + 1];
        if (p.a == ad) {
          imin = std::min(imin, p.i);
          imax = std::max(imax, p.i);
        }
        if ((p.a - ad) * (q.a - ad) < 0.0) {
          const double x = p.i + (ad - p.a) * (q.i - p.i) / (q.a - p.a);
          imin = std::min(imin, x);
          imax = std::max(imax, x);
        }
      }
      if (imin > imax) continue;
      const int64_t ilo = ceil_i(imin - kEps), ihi = floor_i(imax + kEps);
      if (ilo > ihi) continue;
      // Prefer the I that puts the newest step n on its exact time: the next steps continue it.
      const double kn_d = n, i_exact = (T_[n] - static_cast<double>(P_) - 0.5 * kn_d * (kn_d - 1.0) * ad) / kn_d;
      const int64_t i = std::clamp<int64_t>(round_i(i_exact), ilo, ihi);
      any = true;
      ++stats_.verifies;
      const uint32_t bad = first_violation(i, a, n);
      if (bad == 0) {
        I_ = i;
        A_ = a;
        return true;
      }
      if (bad != last_cut) cut = bad;  // else: floating-point edge; try the next add
      // A non-positive interval: the next round clips the positivity constraint instead.
      if (!positivity_clipped && i + static_cast<int64_t>(bad - 1) * a < 1) cut = UINT32_MAX;
    }
    if (!any || cut == 0) return false;
    if (cut == UINT32_MAX) {
      const double kn = n;
      clip(-1.0, -(kn - 1.0), -1.0);  // last interval I + (n-1) A >= 1 (intervals are linear in k)
      positivity_clipped = true;
      continue;
    }
    clip_strip(cut);
    last_cut = cut;
  }
  return false;
}

void StepCompressor::emit() {
  if (n_ == 0) return;
  StepRun run;
  run.interval_ticks = I_;
  run.add_ticks = static_cast<int32_t>(A_);
  run.count = n_;
  run.direction = dir_;
  // check_line: expand the run with the MCU step law before it leaves.
  if (first_violation(I_, A_, n_) != 0 || run_end_clock(P_, run) != pos_) ++stats_.check_failures;
  if (sink_ != nullptr) sink_->on_run(P_, run);
  stats_.runs += 1;
  stats_.steps += n_;
  P_ = pos_;
  last_add_ = A_;
  n_ = 0;
}

void StepCompressor::flush() { emit(); }

}  // namespace feedloop::stepgen
