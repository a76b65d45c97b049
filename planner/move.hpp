// The planner's data: what the interpreter asks for (MoveRequest), what the lookahead emits once a
// move is final (PlannedMove, a closed-form time parametrisation), events (M400, dwell) and the
// sink interface the caller implements. Plain structs, no allocation.
#pragma once

#include <array>
#include <cstdint>

#include "planner/config.hpp"

namespace feedloop::planner {

// A straight move in machine coordinates (mm), already checked against the kinematics.
struct MoveRequest {
  Vec4 end_mm{};              // target X Y Z E (the start is where the previous move ended)
  double velocity_mm_s = 0.0; // requested speed along the path (feedrate after overrides)
  double accel_mm_s2 = 0.0;   // M204 value that applies (P, R or T); further limited per axis
  int line = 0;               // source line, for telemetry
};

// One piece of the path profile: path distance s(tau) = s0 + v0 tau + a0 tau^2/2 + j tau^3/6.
struct ProfilePiece {
  double t_s = 0.0;         // start, relative to the move start
  double duration_s = 0.0;
  double s0_mm = 0.0;
  double v0_mm_s = 0.0;
  double a0_mm_s2 = 0.0;
  double jerk_mm_s3 = 0.0;

  double distance_mm(double tau) const { return s0_mm + tau * (v0_mm_s + tau * (0.5 * a0_mm_s2 + tau * jerk_mm_s3 / 6.0)); }
  double velocity_mm_s(double tau) const { return v0_mm_s + tau * (a0_mm_s2 + 0.5 * tau * jerk_mm_s3); }
  double accel_mm_s2(double tau) const { return a0_mm_s2 + tau * jerk_mm_s3; }
};

// A final move: start time, geometry, trapezoid velocities and the pieces (3 for a trapezoid,
// up to 7 for an S-curve). Position at path distance s is start_mm + unit * s (E included, so the
// extrusion per mm of path is constant along the move).
struct PlannedMove {
  uint64_t index = 0;          // sequence number of the move (0, 1, 2, ...)
  int line = 0;
  double start_time_s = 0.0;   // print time at the start
  double duration_s = 0.0;
  Vec4 start_mm{};
  Vec4 end_mm{};
  Vec4 unit{};                 // d(axis)/ds; for E-only moves unit[kE] = +-1
  double length_mm = 0.0;      // XYZ path length, or |dE| for E-only moves
  bool kinematic = true;       // false for E-only moves
  double accel_mm_s2 = 0.0;    // acceleration used for the trapezoid
  double v_entry_mm_s = 0.0;
  double v_cruise_mm_s = 0.0;
  double v_exit_mm_s = 0.0;
  double accel_t_s = 0.0, cruise_t_s = 0.0, decel_t_s = 0.0;  // trapezoid phases
  std::array<ProfilePiece, 7> pieces{};
  int piece_count = 0;
  bool jerk_bounded = true;    // S-curve: every piece honours the configured jerk bound
  // Pressure advance in effect when the move was queued (0: off); the step stage applies it only
  // to extruding XY moves (planner/pressure_advance.hpp).
  double pressure_advance_s = 0.0;
  double pressure_advance_smooth_time_s = 0.0;

  double end_time_s() const { return start_time_s + duration_s; }
};

// A dwell (G4) as motion: the machine stands at `at_mm` from start_time_s for duration_s (one
// piece of zero velocity). The executors that run a machine queue it so the dwell takes time on
// the machine (Marlin's G4 waits even when nothing moves; an M400 after it waits for its end).
inline PlannedMove standstill_move(const Vec4& at_mm, double start_time_s, double duration_s,
                                   int line) {
  PlannedMove m;
  m.line = line;
  m.start_time_s = start_time_s;
  m.duration_s = duration_s;
  m.start_mm = at_mm;
  m.end_mm = at_mm;
  m.cruise_t_s = duration_s;
  m.pieces[0].duration_s = duration_s;
  m.piece_count = 1;
  return m;
}

enum class EventKind {
  dwell,          // G4: the machine stands still from time_s for duration_s
  moves_done,     // M400: every move planned so far finishes at time_s; the caller may wait on it
  homed,          // G28 finished at time_s
};

struct PlannerEvent {
  EventKind kind = EventKind::moves_done;
  double time_s = 0.0;
  double duration_s = 0.0;
  int line = 0;
};

// Receives final moves in order. Called from the planner's thread; implementations must not block.
class MoveSink {
 public:
  virtual ~MoveSink() = default;
  virtual void on_move(const PlannedMove& move) = 0;
  virtual void on_event(const PlannerEvent& /*event*/) {}
};

}  // namespace feedloop::planner
