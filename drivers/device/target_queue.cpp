// r(t) from a ring of knots (see target_queue.hpp).
#include "drivers/device/target_queue.hpp"

#include "drivers/device/saturate.hpp"

namespace feedloop::device {

void TargetQueue::reset() {
  head_ = count_ = 0;
  piece_valid_ = false;
  last_ = {};
}

bool TargetQueue::push(const TargetKnot& k) {
  if (count_ == kCapacity) return false;
  if (count_ > 0 && k.clock <= last_.clock) return false;
  knots_[(head_ + count_) % kCapacity] = k;
  ++count_;
  last_ = k;
  if (count_ == 2) piece_valid_ = false;
  return true;
}

void TargetQueue::cache_piece() {
  const TargetKnot& a = knots_[head_];
  const TargetKnot& b = knots_[(head_ + 1) % kCapacity];
  inv_duration_ = 1.0f / static_cast<float>(b.clock - a.clock);
  delta_nm_ = static_cast<float>(b.pos_nm - a.pos_nm);
  piece_valid_ = true;
}

TargetSample TargetQueue::at(int64_t clock, float clock_hz) {
  TargetSample s;
  if (count_ == 0) return s;
  s.valid = true;
  // Drop pieces that ended: the head piece [k0, k1) is done once clock >= k1.clock.
  while (count_ >= 2 && knots_[(head_ + 1) % kCapacity].clock <= clock) {
    head_ = (head_ + 1) % kCapacity;
    --count_;
    piece_valid_ = false;
  }
  const TargetKnot& a = knots_[head_];
  if (count_ == 1 || clock < a.clock) {
    s.pos_nm = a.pos_nm;
    s.beyond_horizon = count_ == 1 && clock >= a.clock;
    return s;
  }
  if (!piece_valid_) cache_piece();
  const float frac = static_cast<float>(clock - a.clock) * inv_duration_;
  s.pos_nm = add_saturate_i64(a.pos_nm, saturate_i64(frac * delta_nm_));
  s.velocity_nm_s = delta_nm_ * inv_duration_ * clock_hz;
  return s;
}

}  // namespace feedloop::device
