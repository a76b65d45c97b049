// Sampling planned moves (see sampler.hpp).
#include "planner/sampler.hpp"

#include <algorithm>  // std::clamp

#include "planner/profile.hpp"

namespace feedloop::planner {

CartesianSample sample_move(const PlannedMove& m, double t_s) {
  const PathState st = path_state(m, std::clamp(t_s - m.start_time_s, 0.0, m.duration_s));
  CartesianSample out;
  for (int i = 0; i < kAxes; ++i) {
    out.pos_mm[i] = m.start_mm[i] + m.unit[i] * st.s_mm;
    out.vel_mm_s[i] = m.unit[i] * st.v_mm_s;
    out.accel_mm_s2[i] = m.unit[i] * st.a_mm_s2;
  }
  return out;
}

Joints sample_joints(const Kinematics& kin, const PlannedMove& m, double t_s) {
  const CartesianSample c = sample_move(m, t_s);
  return kin.inverse({c.pos_mm[0], c.pos_mm[1], c.pos_mm[2]});
}

MoveTimeline::MoveTimeline(size_t capacity) : ring_(capacity < 1 ? 1 : capacity) {}

void MoveTimeline::push(const PlannedMove& m) {
  if (count_ == ring_.size()) {
    head_ = (head_ + 1) % ring_.size();
    --count_;
  }
  ring_[(head_ + count_) % ring_.size()] = m;
  ++count_;
}

bool MoveTimeline::sample(double t_s, CartesianSample& out) const {
  if (count_ == 0) return false;
  if (t_s < at(0).start_time_s) {
    out = sample_move(at(0), at(0).start_time_s);
    return false;
  }
  // binary search: last move with start <= t
  size_t lo = 0, hi = count_;
  while (hi - lo > 1) {
    const size_t mid = (lo + hi) / 2;
    if (at(mid).start_time_s <= t_s) lo = mid; else hi = mid;
  }
  const PlannedMove& m = at(lo);
  out = sample_move(m, t_s);
  if (t_s > m.end_time_s()) {
    out.vel_mm_s = {};
    out.accel_mm_s2 = {};
    return lo + 1 < count_ || t_s <= m.end_time_s();
  }
  return true;
}

}  // namespace feedloop::planner
