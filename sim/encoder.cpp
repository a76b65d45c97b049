// Linear encoder and position history (see encoder.hpp).
#include "sim/encoder.hpp"

#include <cmath>  // llround, isfinite

namespace feedloop::sim {

Status validate(const EncoderParams& p) {
  if (!(p.resolution_um > 0.0) || !std::isfinite(p.resolution_um))
    return Error{"encoder.resolution_um must be > 0", {}};
  if (!(p.noise_um >= 0.0) || !std::isfinite(p.noise_um)) return Error{"encoder.noise_um must be >= 0", {}};
  if (!(p.sampling_delay_s >= 0.0) || p.sampling_delay_s > 1.0)
    return Error{"encoder.sampling_delay_s must be in [0, 1] s", {}};
  return Status::Ok();
}

int64_t LinearEncoder::counts(double pos_mm) {
  double pos_um = pos_mm * 1e3;
  if (p_.noise_um > 0.0) pos_um += p_.noise_um * rng_.gaussian();
  return static_cast<int64_t>(std::llround(pos_um / p_.resolution_um));
}

History::History(size_t capacity, double min_spacing_s)
    : t_(capacity < 2 ? 2 : capacity), v_(t_.size()), min_spacing_s_(min_spacing_s) {}

void History::clear(double t_s, double value) {
  head_ = 0;
  size_ = 1;
  t_[0] = t_s;
  v_[0] = value;
}

void History::push(double t_s, double value) {
  if (size_ > 0 && t_s <= t_[head_]) {  // same instant (an event): keep the latest value
    v_[head_] = value;
    return;
  }
  if (size_ > 1 && t_s - t_[(head_ + t_.size() - 1) % t_.size()] < min_spacing_s_) {
    t_[head_] = t_s;  // too close to the sample before the newest: the newest moves up to t_s
    v_[head_] = value;
    return;
  }
  head_ = (head_ + 1) % t_.size();
  t_[head_] = t_s;
  v_[head_] = value;
  if (size_ < t_.size()) ++size_;
}

double History::value_at(double t_s) const {
  if (size_ == 0) return 0.0;
  size_t i = head_;
  if (t_s >= t_[i]) return v_[i];
  for (size_t n = 1; n < size_; ++n) {
    const size_t j = (i + t_.size() - 1) % t_.size();
    if (t_s >= t_[j]) {
      const double f = (t_s - t_[j]) / (t_[i] - t_[j]);
      return v_[j] + f * (v_[i] - v_[j]);
    }
    i = j;
  }
  return v_[i];  // older than the history: the oldest sample
}

}  // namespace feedloop::sim
