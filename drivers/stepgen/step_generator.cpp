// Exact step times from cubic joint segments: see step_generator.hpp for the math.
#include "drivers/stepgen/step_generator.hpp"

#include <algorithm>  // std::sort, std::clamp
#include <cmath>      // sqrt, floor, llround

namespace feedloop::stepgen {

void StepGenerator::configure(double steps_per_mm, TickMap map, StepSink* sink) {
  steps_per_mm_ = steps_per_mm;
  map_ = map;
  sink_ = sink;
  count_ = 0;
}

void StepGenerator::set_position_mm(double pos_mm) {
  n_ = std::llround(pos_mm * steps_per_mm_);
}

void StepGenerator::flush() {
  if (count_ > 0 && sink_ != nullptr) sink_->on_steps(ticks_, dirs_, count_);
  steps_total_ += count_;
  count_ = 0;
}

void StepGenerator::add_segment(const JointSegment& seg) {
  if (!(seg.duration_s > 0.0)) return;
  // s(tau) in steps.
  const double k = steps_per_mm_;
  const double a = seg.c0_mm * k, b = seg.c1_mm_s * k, c = seg.c2_mm_s2 * k, e = seg.c3_mm_s3 * k;
  const double dur = seg.duration_s;
  // Split points: roots of s'(tau) = b + 2c tau + 3e tau^2 inside (0, dur).
  double cuts[4];
  int ncut = 0;
  cuts[ncut++] = 0.0;
  if (e == 0.0) {
    if (c != 0.0) {
      const double tv = -b / (2.0 * c);
      if (tv > 0.0 && tv < dur) cuts[ncut++] = tv;
    }
  } else {
    // 3e tau^2 + 2c tau + b = 0, stable quadratic roots.
    const double A = 3.0 * e, B = 2.0 * c, C = b;
    const double disc = B * B - 4.0 * A * C;
    if (disc > 0.0) {
      const double q = -0.5 * (B + std::copysign(std::sqrt(disc), B));
      double r1 = q / A, r2 = (q != 0.0) ? C / q : r1;
      if (r1 > r2) std::swap(r1, r2);
      if (r1 > 0.0 && r1 < dur) cuts[ncut++] = r1;
      if (r2 > 0.0 && r2 < dur && r2 != r1) cuts[ncut++] = r2;
    }
  }
  cuts[ncut] = dur;
  for (int i = 0; i < ncut; ++i) {
    if (cuts[i + 1] <= cuts[i]) continue;
    if (e == 0.0)
      quadratic_piece(seg.t0_s, a, b, c, cuts[i], cuts[i + 1]);
    else
      cubic_piece(seg.t0_s, a, b, c, e, cuts[i], cuts[i + 1]);
  }
}

// Monotonic quadratic piece on [tau_a, tau_b]. Re-expanded about tau_a:
// s = a1 + b1 u + c u^2, u = tau - tau_a; the threshold x is reached at
// u = 2D / (b1 + d sqrt(b1^2 + 4cD)), D = x - a1 (no cancellation because sign(b1) = d or b1 = 0).
// The thresholds are x0 + d i: their count is known before the loop, and each step's time depends
// on its threshold only, so the loop over a chunk has no branch and no call (a vector loop:
// the file is compiled without errno for sqrt, docs/decisions.md). On x86-64 GCC also builds an
// AVX2 copy (four lanes; no FMA, so every step time is the same bit for bit), chosen at load.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
__attribute__((target_clones("avx2", "default")))
#endif
void StepGenerator::quadratic_piece(double t0_s, double a, double b, double c, double tau_a,
                                    double tau_b) {
  const double a1 = a + tau_a * (b + tau_a * c);
  const double b1 = b + 2.0 * c * tau_a;
  const double du = tau_b - tau_a;
  const double s_end = a1 + du * (b1 + du * c);
  if (s_end == a1) return;
  const int8_t d = s_end > a1 ? 1 : -1;
  const double dd = d;
  // Thresholds x0 + d i, i = 0 .. count - 1, while d (x - s_end) <= 0.
  const double x0 = static_cast<double>(n_) + 0.5 * dd;
  auto inside = [&](int64_t i) { return dd * (x0 + dd * static_cast<double>(i) - s_end) <= 0.0; };
  int64_t count = std::max<int64_t>(0, static_cast<int64_t>(std::floor(dd * (s_end - x0))) + 1);
  while (count > 0 && !inside(count - 1)) --count;  // the floor's rounding, either way
  while (inside(count)) ++count;
  const double t_base = t0_s + tau_a, c4 = 4.0 * c, b1b1 = b1 * b1;
  const double off = map_.offset_ticks, tps = map_.ticks_per_s;
  for (int64_t i = 0; i < count;) {
    const auto m =
        static_cast<size_t>(std::min<int64_t>(static_cast<int64_t>(kChunk - count_), count - i));
    double* out = ticks_ + count_;
    const double xi = x0 + dd * static_cast<double>(i);
    for (int j = 0; j < static_cast<int>(m); ++j) {  // int: converts to double in a vector
      const double D = (xi + dd * static_cast<double>(j)) - a1;
      const double den = b1 + dd * std::sqrt(std::max(0.0, b1b1 + c4 * D));
      const double q = 2.0 * D / den;  // den 0 (b1 = 0 at the start): discarded below
      double u = dd * den > 0.0 ? q : 0.0;
      u = std::min(std::max(u, 0.0), du);
      out[j] = off + tps * (t_base + u);
    }
    std::fill_n(dirs_ + count_, m, d);
    count_ += m;
    n_ += d * static_cast<int64_t>(m);
    i += static_cast<int64_t>(m);
    if (count_ == kChunk) flush();
  }
}

// Monotonic cubic piece: safeguarded Newton per threshold, bracket [previous root, tau_b].
void StepGenerator::cubic_piece(double t0_s, double a, double b, double c, double e,
                                double tau_a, double tau_b) {
  auto s = [&](double t) { return a + t * (b + t * (c + t * e)); };
  auto ds = [&](double t) { return b + t * (2.0 * c + t * 3.0 * e); };
  const double s_a = s(tau_a), s_end = s(tau_b);
  if (s_end == s_a) return;
  const int8_t d = s_end > s_a ? 1 : -1;
  double lo = tau_a;  // s(lo) is before the threshold
  double x = static_cast<double>(n_) + 0.5 * d;
  // 1e-12 s: the compressor treats these times as exact, so their error adds to its bound.
  constexpr double kTolS = 1e-12;
  while ((d > 0) ? (x <= s_end) : (x >= s_end)) {
    double hi = tau_b;
    // Newton start: the root of the second-order Taylor expansion at lo (the same stable
    // formula as the quadratic pieces); its error is O(e u^3), so one Newton step confirms it.
    const double v = ds(lo), w = c + 3.0 * e * lo, D = x - s(lo);
    const double den = v + d * std::sqrt(std::max(0.0, v * v + 4.0 * w * D));
    double t = (den != 0.0) ? lo + 2.0 * D / den : 0.5 * (lo + hi);
    if (!(t > lo && t < hi)) t = 0.5 * (lo + hi);
    double blo = lo;
    for (int it = 0; it < 100; ++it) {
      const double f = (s(t) - x) * d;  // < 0 before the crossing, > 0 after
      if (f < 0.0) blo = t; else hi = t;
      const double fp = ds(t) * d;
      double tn = (fp > 0.0) ? t - f / fp : 0.5 * (blo + hi);
      const bool newton = fp > 0.0 && tn > blo && tn < hi;
      if (!newton) tn = 0.5 * (blo + hi);
      // A Newton step of size delta leaves an error of about delta^2 |s''| / (2 s'): accept
      // its result once that is below kTolS (usually after one step from the Taylor start).
      const double step = std::fabs(tn - t);
      const bool converged = newton && step * step * std::fabs(2.0 * c + 6.0 * e * t) < 2.0 * kTolS * fp;
      const bool done = converged || step < kTolS || hi - blo < kTolS;
      t = tn;
      if (done) break;
    }
    t = std::clamp(t, lo, tau_b);
    n_ += d;
    emit(t0_s + t, d);
    lo = t;
    x += d;
  }
}

}  // namespace feedloop::stepgen
