// Lookahead planner (see lookahead.hpp). The backward pass is Klipper's LookAheadQueue.flush
// restated over a fixed ring buffer.
#include "planner/lookahead.hpp"

#include <algorithm>  // std::min, std::max
#include <cmath>      // sqrt, abs
#include <limits>

#include "planner/junction.hpp"
#include "planner/profile.hpp"
#include "planner/scurve.hpp"

namespace feedloop::planner {

namespace {
constexpr double kMinLength_mm = 1e-9;
}

Planner::Planner(const PlannerConfig& config, MoveSink& sink)
    : cfg_(config), sink_(sink), ring_(config.lookahead_moves), delayed_(config.lookahead_moves),
      delayed_start_(config.lookahead_moves), delayed_end_(config.lookahead_moves),
      position_(config.home_position_mm), jd_mm_(config.junction_deviation()) {}

double Planner::corner_limit_v2(const Queued& prev, const Queued& next) const {
  const double* up = prev.m.unit.data();
  const double* un = next.m.unit.data();
  if (cfg_.cornering == CorneringPolicy::sharp_corner) {
    // Eq. 64-67: m_s is the programmed speed; the paper has no acceleration in the corner.
    const double m_s = std::sqrt(std::min(prev.max_cruise_v2, next.max_cruise_v2));
    const double v = sharp_corner_speed(m_s, corner_angle_deg(up, un), cfg_.sharp);
    return v * v;
  }
  if (cfg_.cornering == CorneringPolicy::speed_change) return speed_change_v2(up, un, cfg_.max_speed_change_mm_s);
  return junction_deviation_v2(up, un, jd_mm_, prev.m.accel_mm_s2, next.m.accel_mm_s2, prev.delta_v2, next.delta_v2);
}

double Planner::reach_v2(const Queued& q, double v2) const {
  if (cfg_.profile != ProfileShape::scurve) return v2 + q.delta_v2;
  const double v = scurve_reach(std::sqrt(v2), q.m.length_mm, q.peak_accel_mm_s2, cfg_.max_jerk_mm_s3);
  return v * v;
}

double Planner::reach_smoothed_v2(const Queued& q, double v2) const {
  if (cfg_.profile != ProfileShape::scurve) return v2 + q.smooth_delta_v2;
  const double v = scurve_reach(std::sqrt(v2), q.m.length_mm * (1.0 - cfg_.min_cruise_ratio), q.peak_accel_mm_s2,
                                cfg_.max_jerk_mm_s3);
  return v * v;
}

double Planner::smoothed_peak_v2(const Queued& q, double start_v2, double end_v2) const {
  if (cfg_.profile != ProfileShape::scurve) return (start_v2 + end_v2 + q.smooth_delta_v2) * 0.5;
  const double v = scurve_peak(std::sqrt(start_v2), std::sqrt(end_v2), q.m.length_mm * (1.0 - cfg_.min_cruise_ratio),
                               q.peak_accel_mm_s2, cfg_.max_jerk_mm_s3);
  return v * v;
}

double Planner::peak_v2(const Queued& q, double start_v2, double end_v2) const {
  if (cfg_.profile != ProfileShape::scurve) return (start_v2 + end_v2 + q.delta_v2) * 0.5;
  const double v = scurve_peak(std::sqrt(start_v2), std::sqrt(end_v2), q.m.length_mm, q.peak_accel_mm_s2, cfg_.max_jerk_mm_s3);
  return v * v;
}

void Planner::add_move(const MoveRequest& req) {
  const Vec4 start = position_;
  Vec4 d{};
  for (int i = 0; i < kAxes; ++i) d[i] = req.end_mm[i] - start[i];
  const double xyz = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  const bool kinematic = xyz > kMinLength_mm;
  const double length = kinematic ? xyz : std::abs(d[kE]);
  if (!(length > kMinLength_mm)) {
    position_ = req.end_mm;
    return;
  }
  if (count_ == ring_.size()) {
    flush_lazy();
    ++lazy_flushes_;
    if (count_ == ring_.size()) {  // window full and nothing final: force one
      plan_and_emit(false, 1);
      ++forced_flushes_;
    }
  }

  Queued& q = at(count_);
  PlannedMove& m = q.m;
  // Every field is assigned here or in emit_front (no struct-wide reset: it is the hot path).
  m.index = next_index_++;
  m.line = req.line;
  m.pressure_advance_s = cfg_.pressure_advance_s;
  m.pressure_advance_smooth_time_s = cfg_.pressure_advance_smooth_time_s;
  m.start_mm = start;
  m.end_mm = req.end_mm;
  m.length_mm = length;
  m.kinematic = kinematic;
  m.piece_count = 0;
  double v = std::min(req.velocity_mm_s, cfg_.max_velocity_mm_s);
  double a = std::min(req.accel_mm_s2, cfg_.max_accel_mm_s2);
  for (int i = 0; i < kAxes; ++i) {
    m.unit[i] = d[i] / length;
    const double u = std::abs(m.unit[i]);
    if (u > 0.0) {
      v = std::min(v, cfg_.max_axis_velocity_mm_s[i] / u);
      a = std::min(a, cfg_.max_axis_accel_mm_s2[i] / u);
    }
  }
  v = std::max(v, 1e-3);  // a zero feedrate would never finish
  m.accel_mm_s2 = a;
  q.peak_accel_mm_s2 = a;

  q.max_cruise_v2 = v * v;
  q.delta_v2 = 2.0 * a * length;
  q.smooth_delta_v2 = 2.0 * a * (1.0 - cfg_.min_cruise_ratio) * length;
  q.max_start_v2 = 0.0;
  q.max_smoothed_v2 = 0.0;
  if (count_ > 0) {
    const Queued& p = at(count_ - 1);
    if (p.m.kinematic && kinematic) {
      q.max_start_v2 = std::min({q.max_cruise_v2, p.max_cruise_v2, reach_v2(p, p.max_start_v2), corner_limit_v2(p, q)});
    }
    q.max_smoothed_v2 = std::min(q.max_start_v2, reach_smoothed_v2(p, p.max_smoothed_v2));
  }
  q.start_v2 = q.cruise_v2 = q.end_v2 = 0.0;
  ++count_;
  position_ = req.end_mm;
}

void Planner::flush_lazy() { plan_and_emit(true, ring_.size()); }

void Planner::flush() { plan_and_emit(false, ring_.size()); }

void Planner::plan_and_emit(bool lazy, size_t max_emit) {
  if (count_ == 0) return;
  bool update_flush_count = lazy;
  size_t flush_count = lazy ? count_ : std::min(count_, max_emit);
  size_t nd = 0;
  double next_end_v2 = 0.0, next_smoothed_v2 = 0.0, peak_cruise_v2 = 0.0;
  auto set_junction = [](Queued& q, double s, double c, double e) {
    q.start_v2 = s;
    q.cruise_v2 = c;
    q.end_v2 = e;
  };
  for (size_t i = count_; i-- > 0;) {
    Queued& mv = at(i);
    const double reachable_start_v2 = reach_v2(mv, next_end_v2);
    const double start_v2 = std::min(mv.max_start_v2, reachable_start_v2);
    const double reachable_smoothed_v2 = reach_smoothed_v2(mv, next_smoothed_v2);
    const double smoothed_v2 = std::min(mv.max_smoothed_v2, reachable_smoothed_v2);
    if (smoothed_v2 < reachable_smoothed_v2) {
      // This move can accelerate.
      if (reach_smoothed_v2(mv, smoothed_v2) > next_smoothed_v2 || nd > 0) {
        // It can decelerate too, or it is a full accel move after a full decel move.
        if (update_flush_count && peak_cruise_v2 > 0.0) {
          flush_count = i;
          update_flush_count = false;
        }
        peak_cruise_v2 = std::min(mv.max_cruise_v2, smoothed_peak_v2(mv, smoothed_v2, next_smoothed_v2));
        if (nd > 0) {
          if (!update_flush_count && i < flush_count) {
            double mc_v2 = peak_cruise_v2;
            for (size_t k = nd; k-- > 0;) {
              mc_v2 = std::min(mc_v2, delayed_start_[k]);
              set_junction(at(delayed_[k]), std::min(delayed_start_[k], mc_v2), mc_v2, std::min(delayed_end_[k], mc_v2));
            }
          }
          nd = 0;
        }
      }
      if (!update_flush_count && i < flush_count) {
        const double cruise_v2 = std::min({peak_v2(mv, start_v2, next_end_v2), mv.max_cruise_v2, peak_cruise_v2});
        set_junction(mv, std::min(start_v2, cruise_v2), cruise_v2, std::min(next_end_v2, cruise_v2));
      }
    } else {
      // Delay this move until peak_cruise_v2 is known.
      delayed_[nd] = i;
      delayed_start_[nd] = start_v2;
      delayed_end_[nd] = next_end_v2;
      ++nd;
    }
    next_end_v2 = start_v2;
    next_smoothed_v2 = smoothed_v2;
  }
  if (update_flush_count || flush_count == 0) return;
  // Moves still delayed at the front accelerate all the way: cruise as the plain pass allows.
  for (size_t k = nd; k-- > 0;) {
    Queued& mv = at(delayed_[k]);
    const double cruise_v2 = std::min(peak_v2(mv, delayed_start_[k], delayed_end_[k]), mv.max_cruise_v2);
    set_junction(mv, std::min(delayed_start_[k], cruise_v2), cruise_v2, std::min(delayed_end_[k], cruise_v2));
  }
  emit_front(flush_count);
}

void Planner::emit_front(size_t n) {
  for (size_t k = 0; k < n; ++k) {
    Queued& q = at(0);
    PlannedMove& m = q.m;
    if (k == 0 && q.start_v2 < last_exit_v2_) {
      // The previous batch already left at last_exit_v2_ (<= this move's reachable start, which
      // emit_front enforced through max_start_v2); a later pass may have capped this move's cruise
      // (minimum-cruise-ratio smoothing) below it. Keep the speed continuous: cruise at least at
      // the entry speed.
      q.start_v2 = last_exit_v2_;
      q.cruise_v2 = std::max(q.cruise_v2, q.start_v2);
    }
    m.v_entry_mm_s = std::sqrt(q.start_v2);
    m.v_cruise_mm_s = std::sqrt(q.cruise_v2);
    m.v_exit_mm_s = std::sqrt(q.end_v2);
    build_profile(m, cfg_.profile, cfg_.max_jerk_mm_s3, q.peak_accel_mm_s2);
    m.start_time_s = print_time_s_;
    print_time_s_ += m.duration_s;
    last_exit_v2_ = q.end_v2;
    sink_.on_move(m);
    if (++head_ == ring_.size()) head_ = 0;
    --count_;
  }
  if (count_ == 0) return;
  // The first queued move now starts at the emitted exit speed; keep the forward bounds
  // (max_start_v2 <= prev.max_start_v2 + prev.delta_v2) consistent with it.
  Queued* prev = &at(0);
  prev->max_start_v2 = std::min(prev->max_start_v2, last_exit_v2_);
  prev->max_smoothed_v2 = std::min(prev->max_smoothed_v2, prev->max_start_v2);
  for (size_t i = 1; i < count_; ++i) {
    Queued& q = at(i);
    const double ms = std::min(q.max_start_v2, reach_v2(*prev, prev->max_start_v2));
    const double sm = std::min({q.max_smoothed_v2, ms, reach_smoothed_v2(*prev, prev->max_smoothed_v2)});
    if (ms == q.max_start_v2 && sm == q.max_smoothed_v2) break;
    q.max_start_v2 = ms;
    q.max_smoothed_v2 = sm;
    prev = &q;
  }
}

void Planner::dwell(double duration_s, int line) {
  flush();
  sink_.on_event({EventKind::dwell, print_time_s_, std::max(0.0, duration_s), line});
  print_time_s_ += std::max(0.0, duration_s);
}

void Planner::wait_for_moves(int line) {
  flush();
  sink_.on_event({EventKind::moves_done, print_time_s_, 0.0, line});
}

void Planner::mark_homed(int line) {
  flush();
  sink_.on_event({EventKind::homed, print_time_s_, 0.0, line});
}

}  // namespace feedloop::planner
