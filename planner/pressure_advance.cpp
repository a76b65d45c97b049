// Smoothed pressure advance (see pressure_advance.hpp for the equations).
#include "planner/pressure_advance.hpp"

#include <algorithm>  // std::min, std::max
#include <cmath>      // std::abs

namespace feedloop::planner {

namespace {

// Integrals over s in [a, b] (a, b on one side of 0) of s^k, k = 0..3, and of s^k |s|.
struct Moments {
  double plain[4];
  double abs[4];
};

Moments moments(double a, double b) {
  Moments m{};
  const double sign = (a + b) >= 0.0 ? 1.0 : -1.0;  // the side of 0 the interval lies on
  double pa = a, pb = b;                            // a^(k+1), b^(k+1)
  for (int k = 0; k < 4; ++k) {
    m.plain[k] = (pb - pa) / (k + 1);
    pa *= a;
    pb *= b;
    m.abs[k] = sign * (pb - pa) / (k + 2);  // integral of s^(k+1) sign(s)
  }
  return m;
}

}  // namespace

bool pressure_advance_applies(const PlannedMove& m) {
  return m.kinematic && m.unit[kE] > 0.0 && (m.unit[kX] != 0.0 || m.unit[kY] != 0.0);
}

PressureAdvance::PressureAdvance(size_t capacity_pieces)
    : ring_(capacity_pieces < 8 ? 8 : capacity_pieces) {}

void PressureAdvance::restart(double e_mm, double smooth_time_s) {
  head_ = count_ = 0;
  h_s_ = std::max(0.0, 0.5 * smooth_time_s);
  start_e_mm_ = rest_e_mm_ = e_mm;
  input_end_s_ = -1e300;
  emitted_s_ = -1e300;
  emitted_e_mm_ = e_mm;
  emitted_v_mm_s_ = 0.0;
}

bool PressureAdvance::push(const PlannedMove& m, double time_offset_s) {
  const double k_s = pressure_advance_applies(m) ? m.pressure_advance_s : 0.0;
  const double u = m.unit[kE];
  const double move_t0 = m.start_time_s + time_offset_s;
  const bool in_time = move_t0 - h_s_ >= emitted_s_ - 1e-9;
  if (!in_time) ++late_moves_;
  if (count_ == 0) start_e_mm_ = m.start_mm[kE];
  for (int i = 0; i < m.piece_count; ++i) {
    const ProfilePiece& p = m.pieces[static_cast<size_t>(i)];
    if (p.duration_s <= 0.0) continue;
    // e(t0 + tau) = c0 + c1 tau + c2 tau^2 + c3 tau^3 (planner/joint_output.cpp's extruder piece)
    const double c0 = m.start_mm[kE] + u * p.s0_mm;
    const double c1 = u * p.v0_mm_s;
    const double c2 = 0.5 * u * p.a0_mm_s2;
    const double c3 = u * p.jerk_mm_s3 / 6.0;
    if (count_ == ring_.size()) {  // full: the oldest goes (the window never reaches it by then)
      start_e_mm_ = ring_[head_].e_end_mm;
      head_ = (head_ + 1) % ring_.size();
      --count_;
    }
    Piece& q = ring_[(head_ + count_) % ring_.size()];
    q.t0_s = move_t0 + p.t_s;
    q.t1_s = q.t0_s + p.duration_s;
    // f = e + K e'
    q.d[0] = c0 + k_s * c1;
    q.d[1] = c1 + 2.0 * k_s * c2;
    q.d[2] = c2 + 3.0 * k_s * c3;
    q.d[3] = c3;
    q.e_end_mm = c0 + p.duration_s * (c1 + p.duration_s * (c2 + p.duration_s * c3));
    ++count_;
    input_end_s_ = q.t1_s;
    rest_e_mm_ = q.e_end_mm;
  }
  // The exact end position (the pieces' sum may differ from end_mm by rounding).
  if (m.piece_count > 0) rest_e_mm_ = m.end_mm[kE];
  return in_time;
}

void PressureAdvance::trim_before(double t_s) {
  // Keep at least one piece (the rest value after the input comes from it).
  while (count_ > 1 && ring_[head_].t1_s < t_s - h_s_) {
    start_e_mm_ = ring_[head_].e_end_mm;
    head_ = (head_ + 1) % ring_.size();
    --count_;
  }
}

size_t PressureAdvance::first_ending_after(double t_s) const {
  size_t lo = 0, hi = count_;  // first piece with t1 > t_s
  while (lo < hi) {
    const size_t mid = (lo + hi) / 2;
    if (at(mid).t1_s > t_s)
      hi = mid;
    else
      lo = mid + 1;
  }
  return lo;
}

bool PressureAdvance::constant_over(double a_s, double b_s, double& value_mm,
                                    double& next_change_s) const {
  if (count_ == 0) {
    value_mm = rest_e_mm_;
    next_change_s = 1e300;
    return true;
  }
  const size_t i = first_ending_after(a_s);
  if (i == count_) {  // after the input: rest at its end
    value_mm = rest_e_mm_;
    next_change_s = 1e300;
    return true;
  }
  const Piece& p = at(i);
  if (p.t0_s <= b_s) return false;  // a piece of motion overlaps [a, b]
  value_mm = i == 0 ? start_e_mm_ : at(i - 1).e_end_mm;
  next_change_s = p.t0_s;
  return true;
}

void PressureAdvance::window_integrals(double t_s, double& weighted, double& signed_sum) const {
  const double h = h_s_;
  const double a = t_s - h, b = t_s + h;
  weighted = 0.0;
  signed_sum = 0.0;
  // f on [x0, x1] (absolute times) as a polynomial in tau = x - t_poly: coefficients d.
  auto add = [&](double x0, double x1, const double* d, double t_poly) {
    if (!(x1 > x0)) return;
    // Shift to s = x - t: tau = s + delta.
    const double delta = t_s - t_poly;
    double e[4];
    e[3] = d[3];
    e[2] = d[2] + 3.0 * d[3] * delta;
    e[1] = d[1] + delta * (2.0 * d[2] + 3.0 * d[3] * delta);
    e[0] = d[0] + delta * (d[1] + delta * (d[2] + delta * d[3]));
    const double s0 = x0 - t_s, s1 = x1 - t_s;
    auto side = [&](double lo, double hi) {
      if (!(hi > lo)) return;
      const Moments m = moments(lo, hi);
      const double sgn = (lo + hi) >= 0.0 ? 1.0 : -1.0;
      for (int k = 0; k < 4; ++k) {
        weighted += e[k] * (h * m.plain[k] - m.abs[k]);
        signed_sum += e[k] * sgn * m.plain[k];
      }
    };
    side(s0, std::min(s1, 0.0));
    side(std::max(s0, 0.0), s1);
  };
  double cursor = a;  // integrated up to here
  for (size_t i = count_ == 0 ? 0 : first_ending_after(a); i < count_; ++i) {
    const Piece& p = at(i);
    if (p.t0_s >= b) break;
    const double rest_mm = i == 0 ? start_e_mm_ : at(i - 1).e_end_mm;
    if (p.t0_s > cursor) {  // rest (a gap, or before the first piece)
      double c[4] = {rest_mm, 0.0, 0.0, 0.0};
      add(cursor, p.t0_s, c, t_s);
      cursor = p.t0_s;
    }
    const double x1 = std::min(p.t1_s, b);
    add(std::max(cursor, p.t0_s), x1, p.d, p.t0_s);
    cursor = x1;
  }
  if (cursor < b) {  // rest after the last piece in the window
    const size_t i = first_ending_after(cursor);
    const double rest_mm = i == count_ ? rest_e_mm_ : (i == 0 ? start_e_mm_ : at(i - 1).e_end_mm);
    double c[4] = {rest_mm, 0.0, 0.0, 0.0};
    add(cursor, b, c, t_s);
  }
}

double PressureAdvance::position_mm(double t_s) const {
  double value = 0.0, next = 0.0;
  if (constant_over(t_s - h_s_, t_s + h_s_, value, next)) return value;  // exactly at rest
  if (h_s_ <= 0.0) return value;  // unused: the advance needs a window (restart with > 0)
  double w = 0.0, sg = 0.0;
  window_integrals(t_s, w, sg);
  return w / (h_s_ * h_s_);
}

double PressureAdvance::velocity_mm_s(double t_s) const {
  double value = 0.0, next = 0.0;
  if (h_s_ <= 0.0 || constant_over(t_s - h_s_, t_s + h_s_, value, next)) return 0.0;
  double w = 0.0, sg = 0.0;
  window_integrals(t_s, w, sg);
  return sg / (h_s_ * h_s_);
}

}  // namespace feedloop::planner
