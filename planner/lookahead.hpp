// The lookahead planner: a bounded window of moves, velocity/acceleration limits per axis and
// along the path, cornering (junction deviation, the sharp-corner assignment or the thesis's
// speed change), Klipper's minimum cruise ratio, and deceleration planning so that the machine
// can always stop at the end of the queued moves. Moves leave through the MoveSink as soon as
// later moves can no longer change them (Klipper's lazy flush), each with a closed-form profile
// (profile.hpp).
//
// Algorithm (Klipper toolhead.py LookAheadQueue, restated):
//   per move:  max_cruise_v2 = v^2, delta_v2 = 2 a L, smooth_delta_v2 = 2 a (1 - min_cruise_ratio) L
//   junction:  max_start_v2 = min(v^2, v_prev^2, corner limit, prev.max_start_v2 + prev.delta_v2)
//   (with the S-curve, "+ delta_v2" and the cruise peak are jerk-limited: scurve.hpp)
//   backward pass from the end of the queue assuming a stop there: start_v2 = min(max_start_v2,
//   next_start_v2 + delta_v2); the "smoothed" pass with smooth_delta_v2 caps the cruise speed
//   of accelerate-then-decelerate moves (peak_cruise_v2).
// Memory: the window is allocated once (config.lookahead_moves); add_move allocates nothing.
// Owner: the planner thread.
#pragma once

#include <cstdint>
#include <vector>

#include "planner/move.hpp"

namespace feedloop::planner {

class Planner {
 public:
  Planner(const PlannerConfig& config, MoveSink& sink);

  // Queues a straight move from the current end of the queue to req.end_mm. Zero-length moves
  // are dropped. May emit final moves to the sink. RT-friendly: no allocation.
  void add_move(const MoveRequest& req);
  // Plans every queued move to a stop and emits them all.
  void flush();
  // Emits the moves that later additions can no longer change (called automatically when the
  // window is full; a daemon may call it on a timer to bound latency).
  void flush_lazy();
  // G4: flush, then stand still for duration_s (a dwell event).
  void dwell(double duration_s, int line);
  // M400: flush, then report a moves_done event at the time the last move ends.
  void wait_for_moves(int line);
  // G28 in simulation: an event after the homing move was flushed.
  void mark_homed(int line);

  // Position at the end of the queue (machine coordinates) and setting it while the queue is empty.
  const Vec4& position() const { return position_; }
  void set_position(const Vec4& p) { position_ = p; }
  void set_junction_deviation(double jd_mm) { jd_mm_ = jd_mm; }
  // M900 / SET_PRESSURE_ADVANCE: carried by the moves added from now on
  // (planner/pressure_advance.hpp).
  void set_pressure_advance(double advance_s, double smooth_time_s) {
    cfg_.pressure_advance_s = advance_s;
    cfg_.pressure_advance_smooth_time_s = smooth_time_s;
  }
  // M203 / M201: per-axis limits for the moves added from now on.
  void set_axis_limits(const Vec4& max_velocity_mm_s, const Vec4& max_accel_mm_s2) {
    cfg_.max_axis_velocity_mm_s = max_velocity_mm_s;
    cfg_.max_axis_accel_mm_s2 = max_accel_mm_s2;
  }
  double junction_deviation() const { return jd_mm_; }

  double print_time_s() const { return print_time_s_; }  // end of the last emitted move or dwell
  uint64_t moves_added() const { return next_index_; }
  size_t queued() const { return count_; }
  // Times the window was full with no final move, so the oldest was planned to a possible stop.
  uint64_t forced_flushes() const { return forced_flushes_; }
  uint64_t lazy_flushes() const { return lazy_flushes_; }
  const PlannerConfig& config() const { return cfg_; }

 private:
  struct Queued {
    PlannedMove m;
    double max_start_v2, max_cruise_v2, delta_v2, max_smoothed_v2, smooth_delta_v2;
    double start_v2, cruise_v2, end_v2;
    double peak_accel_mm_s2;  // S-curve peak bound (the move's accel limit)
  };
  Queued& at(size_t i) {
    size_t k = head_ + i;
    if (k >= ring_.size()) k -= ring_.size();
    return ring_[k];
  }
  void plan_and_emit(bool lazy, size_t max_emit);
  void emit_front(size_t n);
  double corner_limit_v2(const Queued& prev, const Queued& next) const;
  // Highest speed^2 reachable over the move from speed^2 v2 (v2 + 2 a L, or jerk-limited), and
  // the highest cruise speed^2 between the given start and end (S-curve: scurve.hpp).
  double reach_v2(const Queued& q, double v2) const;
  double peak_v2(const Queued& q, double start_v2, double end_v2) const;
  // The same over (1 - min_cruise_ratio) of the move: Klipper's accel-to-decel smoothing.
  double reach_smoothed_v2(const Queued& q, double v2) const;
  double smoothed_peak_v2(const Queued& q, double start_v2, double end_v2) const;

  PlannerConfig cfg_;
  MoveSink& sink_;
  std::vector<Queued> ring_;
  std::vector<size_t> delayed_;  // scratch for the backward pass, sized once
  std::vector<double> delayed_start_, delayed_end_;
  size_t head_ = 0, count_ = 0;
  Vec4 position_{};
  double jd_mm_;
  double print_time_s_ = 0.0;
  double last_exit_v2_ = 0.0;  // exit speed^2 of the last emitted move
  uint64_t next_index_ = 0;
  uint64_t forced_flushes_ = 0, lazy_flushes_ = 0;
};

}  // namespace feedloop::planner
