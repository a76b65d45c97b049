// Weighted regression of MCU clock on host time: see clock_sync.hpp.
#include "drivers/clock_sync.hpp"

#include <algorithm>  // std::min, std::nth_element
#include <cmath>      // fabs

namespace feedloop::drivers {

void ClockSync::configure(const ClockSyncParams& p) {
  p_ = p;
  if (p_.window < 2) p_.window = 2;
  ring_.assign(static_cast<size_t>(p_.window), Sample{});
  scratch_.reserve(static_cast<size_t>(p_.window));  // fit() then never allocates
  head_ = count_ = 0;
  est_ = ClockEstimate{};
  est_.freq_hz_ = p_.nominal_hz;
}

void ClockSync::add_sample(double send_s, double recv_s, int64_t mcu_clock) {
  if (recv_s < send_s) return;
  est_.last_rtt_s_ = recv_s - send_s;
  ring_[static_cast<size_t>((head_ + count_) % p_.window)] = {0.5 * (send_s + recv_s), recv_s - send_s, mcu_clock};
  if (count_ < p_.window) ++count_; else head_ = (head_ + 1) % p_.window;
  fit();
  est_.samples_ = count_;
  est_.mean_rtt_s_ = window_mean_rtt_s();
}

double ClockSync::window_mean_rtt_s() const {
  if (count_ == 0) return 0.0;
  double sum = 0.0;
  for (int i = 0; i < count_; ++i) sum += ring_[static_cast<size_t>((head_ + i) % p_.window)].rtt_s;
  return sum / count_;
}

void ClockSync::fit() {
  const auto at = [&](int i) -> const Sample& { return ring_[static_cast<size_t>((head_ + i) % p_.window)]; };
  // Keep the fast round trips: within rtt_floor of the fastest, or within twice the spread of
  // the fastest quarter (a slow round trip, e.g. a retransmitted query, says little about when
  // the MCU read its clock, and many of them may be slow).
  scratch_.clear();
  for (int i = 0; i < count_; ++i) scratch_.push_back(at(i).rtt_s);
  std::nth_element(scratch_.begin(), scratch_.begin() + count_ / 4, scratch_.end());
  const double q25_rtt = scratch_[static_cast<size_t>(count_ / 4)];
  double min_rtt = at(0).rtt_s;
  for (int i = 1; i < count_; ++i) min_rtt = std::min(min_rtt, at(i).rtt_s);
  est_.min_rtt_s_ = min_rtt;
  const double keep_rtt = min_rtt + std::max(p_.rtt_floor_s, 2.0 * (q25_rtt - min_rtt));
  // Reference point: the newest sample (keeps the numbers small).
  const Sample& ref = at(count_ - 1);
  double sw = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  double span_lo = 1e300, span_hi = -1e300;
  for (int i = 0; i < count_; ++i) {
    const Sample& s = at(i);
    if (s.rtt_s > keep_rtt) continue;
    const double x = s.mid_s - ref.mid_s;
    const double y = static_cast<double>(s.clock - ref.clock);
    sw += 1.0;
    sx += x;
    sy += y;
    sxx += x * x;
    sxy += x * y;
    span_lo = std::min(span_lo, s.mid_s);
    span_hi = std::max(span_hi, s.mid_s);
  }
  const double mx = sx / sw, my = sy / sw;
  const double vxx = sxx / sw - mx * mx;
  double f = p_.nominal_hz;
  if (sw >= 2 && span_hi - span_lo >= p_.min_span_s && vxx > 0.0) {
    f = (sxy / sw - mx * my) / vxx;
    // A wild slope (too few good samples) is worse than the nominal frequency.
    if (std::fabs(f / p_.nominal_hz - 1.0) > 0.01) f = p_.nominal_hz;
  }
  est_.freq_hz_ = f;
  est_.m_ref_ = ref.mid_s + mx;
  est_.c_ref_ = static_cast<double>(ref.clock) + my;

  // Refinement by interval intersection: the MCU read its clock at some tau_i in [s_i, r_i], so
  // a line c = o + f (t - t0) through all samples must satisfy
  //   c_i - f (r_i - t0) <= o <= c_i - f (s_i - t0)   for every i.
  // For a given f the feasible offsets form an interval of width w(f), a concave function of f;
  // the line in the middle of the widest interval (the most central line, which only depends on
  // the fastest up and down trips, not on averages) is the estimate. If no line fits all
  // samples (the clock's rate changed), the regression stays.
  const double t0 = ref.mid_s;
  auto width = [&](double fq, double& o_mid) {
    double lo = -1e300, hi = 1e300;
    for (int i = 0; i < count_; ++i) {
      const Sample& s = at(i);
      const double c = static_cast<double>(s.clock - ref.clock);
      lo = std::max(lo, c - fq * (s.mid_s + 0.5 * s.rtt_s - t0));
      hi = std::min(hi, c - fq * (s.mid_s - 0.5 * s.rtt_s - t0));
    }
    o_mid = 0.5 * (lo + hi);
    return hi - lo;
  };
  if (count_ >= 3 && span_hi - span_lo >= p_.min_span_s) {
    double a = f * (1.0 - 5e-4), b = f * (1.0 + 5e-4), o = 0.0;
    for (int it = 0; it < 80; ++it) {  // ternary search of the concave width
      const double m1 = a + (b - a) / 3.0, m2 = b - (b - a) / 3.0;
      if (width(m1, o) < width(m2, o)) a = m1; else b = m2;
    }
    const double fc = 0.5 * (a + b);
    if (width(fc, o) >= 0.0) {
      est_.freq_hz_ = fc;
      est_.m_ref_ = t0;
      est_.c_ref_ = static_cast<double>(ref.clock) + o;
      return;
    }
  }
  // Frequency not yet known well: intersect the recent samples with the regression's f.
  double lo = -1e300, hi = 1e300;
  const int first = std::max(0, count_ - p_.offset_window);
  for (int i = first; i < count_; ++i) {
    const Sample& s = at(i);
    const double c = static_cast<double>(s.clock - ref.clock);
    lo = std::max(lo, c - f * (s.mid_s + 0.5 * s.rtt_s - t0));
    hi = std::min(hi, c - f * (s.mid_s - 0.5 * s.rtt_s - t0));
  }
  if (lo <= hi) {
    est_.m_ref_ = t0;
    est_.c_ref_ = static_cast<double>(ref.clock) + 0.5 * (lo + hi);
  }
}

}  // namespace feedloop::drivers
