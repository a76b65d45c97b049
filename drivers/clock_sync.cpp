// Weighted regression of MCU clock on host time: see clock_sync.hpp.
#include "drivers/clock_sync.hpp"

#include <algorithm>  // std::min
#include <cmath>      // fabs

namespace feedloop::drivers {

void ClockSync::configure(const ClockSyncParams& p) {
  p_ = p;
  if (p_.window < 2) p_.window = 2;
  ring_.assign(static_cast<size_t>(p_.window), Sample{});
  head_ = count_ = 0;
  freq_hz_ = p_.nominal_hz;
}

void ClockSync::add_sample(double send_s, double recv_s, int64_t mcu_clock) {
  if (recv_s < send_s) return;
  ring_[static_cast<size_t>((head_ + count_) % p_.window)] = {0.5 * (send_s + recv_s), recv_s - send_s, mcu_clock};
  if (count_ < p_.window) ++count_; else head_ = (head_ + 1) % p_.window;
  fit();
}

void ClockSync::fit() {
  const auto at = [&](int i) -> const Sample& { return ring_[static_cast<size_t>((head_ + i) % p_.window)]; };
  double min_rtt = at(0).rtt_s;
  for (int i = 1; i < count_; ++i) min_rtt = std::min(min_rtt, at(i).rtt_s);
  min_rtt_s_ = min_rtt;
  // Reference point: the newest sample (keeps the numbers small).
  const Sample& ref = at(count_ - 1);
  double sw = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  double span_lo = 1e300, span_hi = -1e300;
  for (int i = 0; i < count_; ++i) {
    const Sample& s = at(i);
    const double e = s.rtt_s - min_rtt + p_.rtt_floor_s;
    const double w = 1.0 / (e * e);
    const double x = s.mid_s - ref.mid_s;
    const double y = static_cast<double>(s.clock - ref.clock);
    sw += w;
    sx += w * x;
    sy += w * y;
    sxx += w * x * x;
    sxy += w * x * y;
    if (w * p_.rtt_floor_s * p_.rtt_floor_s > 0.1) {  // samples near the minimum RTT
      span_lo = std::min(span_lo, s.mid_s);
      span_hi = std::max(span_hi, s.mid_s);
    }
  }
  const double mx = sx / sw, my = sy / sw;
  const double vxx = sxx / sw - mx * mx;
  double f = p_.nominal_hz;
  if (count_ >= 2 && span_hi - span_lo >= p_.min_span_s && vxx > 0.0) {
    f = (sxy / sw - mx * my) / vxx;
    // A wild slope (too few good samples) is worse than the nominal frequency.
    if (std::fabs(f / p_.nominal_hz - 1.0) > 0.01) f = p_.nominal_hz;
  }
  freq_hz_ = f;
  m_ref_ = ref.mid_s + mx;
  c_ref_ = static_cast<double>(ref.clock) + my;
}

}  // namespace feedloop::drivers
