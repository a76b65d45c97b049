// Pressure advance, Klipper's smoothed form (Klipper docs: Pressure_Advance.md, and Kinematics.md
// "Pressure advance"; Marlin's M900 K is the same linear term without the smoothing).
//
// The extruder's nominal position e(t) is the planner's E (piecewise polynomial in time, exact per
// profile piece). The advanced position is
//
//   f(t)     = e(t) + K_m * de/dt                                   (pa_position)
//   e_adv(t) = integral_{-h}^{+h} f(t + s) * (h - |s|) / h^2 ds,   h = smooth_time / 2
//
// K_m is the move's pressure_advance_s when the move extrudes (dE > 0) while X or Y moves, and 0
// otherwise (retracts, E-only priming, travel): Klipper applies the advance only to such moves
// (extruder.py, "can_pressure_advance"). The triangular window of total width smooth_time
// (symmetric, weight integral 1) makes e_adv continuous with bounded velocity although f jumps
// wherever the extrusion rate jumps (K v), and it adds no delay (symmetric). Outside the moves
// (before, in dwells, after) e is at rest: f = e, so e_adv returns exactly to e once the window
// has passed, and the step count at rest is unchanged.
//
// Its derivative (for the Hermite pieces below) needs no derivative of f, whose jumps it handles:
//   de_adv/dt = ( integral_{0}^{h} f(t + s) ds - integral_{-h}^{0} f(t + s) ds ) / h^2
//
// Both integrals are evaluated in closed form: on each polynomial piece of f, rewritten in
// s = x - t, integral s^k (h -+ s) ds and integral s^k ds.
//
// Output: cubic Hermite JointSegments (c0..c3) on the servo grid through the exact e_adv and its
// derivative at the knots (position continuous, exact at every knot; over a 1 ms piece the
// interpolation error of the degree-5 e_adv is below 1e-6 mm). Where the whole window lies in a
// rest interval the output is one constant segment up to the next change.
//
// Fixed capacity (the pieces of the last moves), no allocation after construction: RT-safe.
#pragma once

#include <algorithm>  // std::min
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/joint_segment.hpp"
#include "planner/move.hpp"

namespace feedloop::planner {

struct PressureAdvanceLimits {
  static constexpr double kMaxAdvance_s = 10.0;      // Marlin's M900 K range is 0..10
  static constexpr double kMaxSmoothTime_s = 0.200;  // Klipper's pressure_advance_smooth_time max
};

// True when a move gets the advance (Klipper: positive extrusion while X or Y moves).
bool pressure_advance_applies(const PlannedMove& m);

class PressureAdvance {
 public:
  explicit PressureAdvance(size_t capacity_pieces = 16384);

  // At rest: E at `e_mm`, no pieces. The advance (re)starts with a window of smooth_time_s (the
  // window changes only here: Klipper, too, flushes the motion before a new smooth time acts).
  void restart(double e_mm, double smooth_time_s);
  // Appends the E pieces of a move, its times shifted by `time_offset_s` (the caller's time base).
  // Moves arrive in time order. Returns false (and counts it in late_moves()) when the move starts
  // less than h after the output already emitted: that output assumed rest, so e_adv steps by the
  // part of the move's advance already inside the window, spread over the next Hermite piece (the
  // executors avoid it: they take moves h early and start a motion h late). RT-safe.
  bool push(const PlannedMove& m, double time_offset_s = 0.0);
  // e_adv(t) and its derivative. RT-safe.
  double position_mm(double t_s) const;
  double velocity_mm_s(double t_s) const;

  // Joint segments of e_adv from where the last call ended up to `until_s`, knots every `period_s`
  // (the caller passes until_s <= input_end_s() - half_window_s() while more moves may come, or
  // more once the input has ended: the rest after the last move is then assumed). RT-safe.
  template <class Sink>
  void emit_until(double until_s, double period_s, Sink&& sink);
  double emitted_until_s() const { return emitted_s_; }
  void set_emitted_from(double t_s) { emitted_s_ = t_s; }

  double half_window_s() const { return h_s_; }
  double input_end_s() const { return input_end_s_; }  // end of the last pushed piece
  double rest_e_mm() const { return rest_e_mm_; }      // E at the end of the input
  bool empty() const { return count_ == 0; }
  uint64_t late_moves() const { return late_moves_; }
  // Drops the pieces that no window at or after t_s can reach. RT-safe.
  void trim_before(double t_s);

 private:
  struct Piece {
    double t0_s, t1_s;
    double d[4];  // f(t0 + tau) = d0 + d1 tau + d2 tau^2 + d3 tau^3 (e + K e')
    double e_end_mm;
  };
  const Piece& at(size_t i) const { return ring_[(head_ + i) % ring_.size()]; }
  // Sums over [t - h, t + h] of f against (h - |s|) (pos) and sign(s) (vel).
  void window_integrals(double t_s, double& weighted, double& signed_sum) const;
  // True when f is constant over [a, b]: then value_mm is that constant.
  bool constant_over(double a_s, double b_s, double& value_mm, double& next_change_s) const;
  size_t first_ending_after(double t_s) const;

  std::vector<Piece> ring_;
  size_t head_ = 0, count_ = 0;
  double h_s_ = 0.0;
  double start_e_mm_ = 0.0;  // E before the first piece
  double rest_e_mm_ = 0.0;   // E after the last piece
  double input_end_s_ = -1e300;
  double emitted_s_ = -1e300;
  double emitted_e_mm_ = 0.0, emitted_v_mm_s_ = 0.0;
  uint64_t late_moves_ = 0;
};

template <class Sink>
void PressureAdvance::emit_until(double until_s, double period_s, Sink&& sink) {
  constexpr double kMinPiece_s = 1e-9;
  if (emitted_s_ < -1e299)
    emitted_s_ = until_s;  // never started (set_emitted_from): nothing to join
  while (emitted_s_ < until_s - kMinPiece_s) {
    const double ta = emitted_s_;
    double value = 0.0, next_change = 0.0;
    JointSegment seg;
    seg.t0_s = ta;
    if (constant_over(ta - h_s_, ta + period_s + h_s_, value, next_change)) {
      // The window sees only rest from ta on until next_change - h.
      double tb = std::min(until_s, next_change - h_s_);
      if (tb < ta + period_s) tb = std::min(until_s, ta + period_s);
      seg.duration_s = tb - ta;
      seg.c0_mm = value;
      sink(seg);
      emitted_s_ = tb;
      emitted_e_mm_ = value;
      emitted_v_mm_s_ = 0.0;
      continue;
    }
    const double tb = std::min(until_s, ta + period_s);
    const double hd = tb - ta;
    const double qa = emitted_e_mm_, va = emitted_v_mm_s_;
    const double qb = position_mm(tb), vb = velocity_mm_s(tb);
    const double slope = (qb - qa) / hd;
    seg.duration_s = hd;
    seg.c0_mm = qa;
    seg.c1_mm_s = va;
    seg.c2_mm_s2 = (3.0 * slope - 2.0 * va - vb) / hd;
    seg.c3_mm_s3 = (va + vb - 2.0 * slope) / (hd * hd);
    sink(seg);
    emitted_s_ = tb;
    emitted_e_mm_ = qb;
    emitted_v_mm_s_ = vb;
  }
}

}  // namespace feedloop::planner
