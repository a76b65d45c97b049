// Greedy run compression with a lazily clipped feasible polygon: see step_compressor.hpp.
#include "drivers/stepgen/step_compressor.hpp"

#include <algorithm>  // std::min, std::max, std::clamp
#include <cmath>      // ceil, floor, llround

namespace feedloop::stepgen {

namespace {
constexpr double kAddBound = 1e7;  // |A| box before the second step bounds it (ticks)
constexpr double kEps = 1e-7;      // slack for the floating polygon; runs are verified exactly
constexpr int kAddTries = 24;      // integer adds tried around the polygon's centre
}  // namespace

void StepCompressor::configure(const StepCompressorParams& params, RunSink* sink) {
  params_ = params;
  if (params_.max_run_count < 1) params_.max_run_count = 1;
  sink_ = sink;
  T_.assign(params_.max_run_count + 2, 0.0);
  lo_.assign(params_.max_run_count + 2, 0.0);
  stats_ = {};
  reset(0, 0.0);
}

void StepCompressor::reset(int64_t last_step_clock, double last_step_target_ticks) {
  P_ = last_step_clock;
  prev_target_ = last_step_target_ticks;
  n_ = 0;
  nv_ = 0;
  poly_upto_ = 0;
}

void StepCompressor::push(double target, int8_t direction) {
  const double lo =
      target - std::min(params_.max_error_ticks, 0.5 * (target - prev_target_));
  prev_target_ = target;
  if (n_ > 0 && direction != dir_) emit();
  dir_ = direction;
  const uint32_t k = n_ + 1;
  T_[k] = target;
  lo_[k] = lo;
  if (n_ == 0) {
    start_run_with_first_point();
    return;
  }
  if (k <= params_.max_run_count) {
    // Fast path: the candidate's next step, two integer additions.
    const int64_t m = pos_ + iv_;
    const double rel = static_cast<double>(m - P_);
    if (iv_ >= 1 && rel >= lower(k) && rel <= upper(k)) {
      pos_ = m;
      iv_ += A_;
      n_ = k;
      return;
    }
    if (search_candidate(k)) {
      const int64_t kk = k;
      pos_ = P_ + kk * I_ + A_ * (kk * (kk - 1) / 2);
      iv_ = I_ + kk * A_;
      n_ = k;
      return;
    }
  }
  emit();
  T_[1] = target;
  lo_[1] = lo;
  start_run_with_first_point();
}

void StepCompressor::start_run_with_first_point() {
  const double L = lower(1), U = upper(1);
  const double lo_i = std::max(1.0, std::ceil(L)), hi_i = std::floor(U);
  int64_t I = std::llround(T_[1] - static_cast<double>(P_));
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
  nv_ = 0;
  poly_upto_ = 0;
  poly_overflow_ = false;
}

void StepCompressor::clip(double ni, double na, double c) {
  if (nv_ == 0) return;
  int m = 0;
  for (int j = 0; j < nv_; ++j) {
    const Vertex& p = poly_[j];
    const Vertex& q = poly_[(j + 1) % nv_];
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
  std::copy(tmp_, tmp_ + m, poly_);
}

bool StepCompressor::verify(int64_t I, int64_t A, uint32_t n) const {
  int64_t rel = 0, iv = I;
  for (uint32_t k = 1; k <= n; ++k) {
    if (iv < 1) return false;
    rel += iv;
    const double r = static_cast<double>(rel);
    if (r < lower(k) || r > upper(k)) return false;
    iv += A;
  }
  return true;
}

bool StepCompressor::search_candidate(uint32_t n) {
  ++stats_.candidate_searches;
  if (poly_overflow_) return false;
  if (poly_upto_ == 0) {
    const double lo_i = std::max(1.0, lower(1)), hi_i = upper(1);
    if (lo_i > hi_i) return false;
    poly_[0] = {lo_i, -kAddBound};
    poly_[1] = {hi_i, -kAddBound};
    poly_[2] = {hi_i, kAddBound};
    poly_[3] = {lo_i, kAddBound};
    nv_ = 4;
    poly_upto_ = 1;
  }
  for (uint32_t k = poly_upto_ + 1; k <= n && nv_ > 0; ++k) {
    const double kk = k, tk = 0.5 * kk * (kk - 1.0);
    clip(kk, tk, upper(k));
    clip(-kk, -tk, -lower(k));
    clip(-1.0, -(kk - 1.0), -1.0);  // interval before step k: I + (k-1) A >= 1
  }
  poly_upto_ = n;
  if (nv_ < 3) return false;

  double amin = poly_[0].a, amax = poly_[0].a, ca = 0.0;
  for (int j = 0; j < nv_; ++j) {
    amin = std::min(amin, poly_[j].a);
    amax = std::max(amax, poly_[j].a);
    ca += poly_[j].a;
  }
  ca /= nv_;
  const double alo_d = std::ceil(amin - kEps), ahi_d = std::floor(amax + kEps);
  if (alo_d > ahi_d) return false;
  const int64_t alo = static_cast<int64_t>(alo_d), ahi = static_cast<int64_t>(ahi_d);
  const int64_t a0 = std::clamp<int64_t>(std::llround(ca), alo, ahi);
  for (int t = 0; t < kAddTries; ++t) {
    const int64_t a = (t & 1) ? a0 + (t + 1) / 2 : a0 - t / 2;
    if (a < alo || a > ahi) {
      if (a0 + (t + 2) / 2 > ahi && a0 - (t + 1) / 2 < alo) break;
      continue;
    }
    // Range of I on the line A = a.
    const double ad = static_cast<double>(a);
    double imin = 1e300, imax = -1e300;
    for (int j = 0; j < nv_; ++j) {
      const Vertex& p = poly_[j];
      const Vertex& q = poly_[(j + 1) % nv_];
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
    const double ilo_d = std::ceil(imin - kEps), ihi_d = std::floor(imax + kEps);
    if (ilo_d > ihi_d) continue;
    const int64_t ilo = static_cast<int64_t>(ilo_d), ihi = static_cast<int64_t>(ihi_d);
    const int64_t i0 = std::clamp<int64_t>(std::llround(0.5 * (imin + imax)), ilo, ihi);
    for (int64_t di : {int64_t{0}, int64_t{1}, int64_t{-1}}) {
      const int64_t i = i0 + di;
      if (i < ilo || i > ihi) continue;
      if (verify(i, a, n)) {
        I_ = i;
        A_ = a;
        return true;
      }
    }
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
  if (!verify(I_, A_, n_) || run_end_clock(P_, run) != pos_) ++stats_.check_failures;
  if (sink_ != nullptr) sink_->on_run(P_, run);
  stats_.runs += 1;
  stats_.steps += n_;
  P_ = pos_;
  last_add_ = A_;
  n_ = 0;
}

void StepCompressor::flush() { emit(); }

}  // namespace feedloop::stepgen
