// The second simulator's linear encoder (see encoder.hpp).
#include "plant2/encoder.hpp"

#include <algorithm>
#include <cmath>

namespace feedloop::plant2 {

Encoder::Encoder(const EncoderParams& p, double origin_m, double step_s)
    : p_(p), origin_m_(origin_m), min_spacing_s_(0.5 * step_s) {
  // Enough samples for the longest delay at half the step (push() keeps the spacing), plus margin.
  const double steps = std::ceil(std::max(p.max_delay_s, p.delay_s) / std::max(0.5 * step_s, 1e-9));
  const size_t n = static_cast<size_t>(steps) + 8;
  t_.assign(n, 0.0);
  x_.assign(n, origin_m);
}

void Encoder::push(double t_s, double x_m) {
  const size_t n = t_.size();
  if (count_ >= 2) {
    // Too close to the newest held sample: it moves up to now (the one before stays), so the
    // spacing between held samples never falls below half a step.
    const size_t newest = (head_ + n - 1) % n;
    const size_t before = (head_ + n - 2) % n;
    if (t_s - t_[before] < 2.0 * min_spacing_s_) {
      t_[newest] = t_s;
      x_[newest] = x_m;
      return;
    }
  }
  t_[head_] = t_s;
  x_[head_] = x_m;
  head_ = (head_ + 1) % t_.size();
  count_ = std::min(count_ + 1, t_.size());
}

double Encoder::delayed_m(double t_s) const {
  if (count_ == 0) return origin_m_;
  const size_t n = t_.size();
  const double target = t_s - p_.delay_s;
  size_t i = (head_ + n - 1) % n;  // newest
  if (target >= t_[i]) return x_[i];
  // Walk back to the first sample at or before the target.
  for (size_t k = 1; k < count_; ++k) {
    const size_t j = (i + n - 1) % n;
    if (t_[j] <= target) {
      const double span = t_[i] - t_[j];
      const double w = span > 0.0 ? (target - t_[j]) / span : 1.0;
      return x_[j] + w * (x_[i] - x_[j]);
    }
    i = j;
  }
  return x_[i];  // before the oldest held sample: at rest at power-on
}

double Encoder::reading_of(double x_m) const {
  constexpr double kTwoPi = 6.283185307179586;
  double y = origin_m_ + p_.scale * (x_m - origin_m_);
  if (p_.interp_amplitude_m != 0.0 && p_.interp_period_m > 0.0)
    y += p_.interp_amplitude_m * std::sin(kTwoPi * x_m / p_.interp_period_m + p_.interp_phase_rad);
  return y;
}

double Encoder::quantised_m(double t_s) const {
  const double y = raw_m(t_s);
  if (!(p_.resolution_m > 0.0)) return y;
  return std::round(y / p_.resolution_m) * p_.resolution_m;
}

}  // namespace feedloop::plant2
