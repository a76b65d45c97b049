// The G-code machine state and its execution: turns gcode::Commands into planner moves.
//   G0/G1 lines, G2/G3 arcs (I J or R, split within config.arc_tolerance_mm), G4 dwell,
//   G10/G11 firmware retraction (M207/M208 set it), G17 (only the XY plane), G20/G21 units,
//   G28 home (simulated: a move to config.home_position_mm; marks the axes homed), G90/G91, G92
//   (incl. G92 E0), M18/M84 (motors off: the axes are no longer homed, as in Marlin),
//   M82/M83, M220/M221 overrides (M220 B/R back up/restore), M400 (a moves_done event the caller
//   can wait on), M201/M203 per-axis limits, M204 P/R/T/S as Marlin 2 defines them (P printing
//   moves, R E-only retract moves, T travel moves, S legacy = P and T), M205 J junction deviation.
//   M205 X/Y/Z/E (classic jerk) are recorded but not used for planning: Marlin 2 ignores them
//   too when CLASSIC_JERK is off (junction deviation is the cornering model then).
//   M900 K (Marlin's linear advance factor) and Klipper's SET_PRESSURE_ADVANCE ADVANCE=
//   SMOOTH_TIME= (the parser turns it into M900 with text "SET_PRESSURE_ADVANCE", K and S): the
//   values travel with every move (planner/pressure_advance.hpp applies them); a new smooth time
//   acts from the next start from rest.
//   Object labels (Klipper's EXCLUDE_OBJECT_DEFINE / _START / _END and EXCLUDE_OBJECT, which the
//   parser gives as M486.1-.4, planner/object_labels.hpp): while the current object is excluded,
//   its G0-G3 and G10/G11 change the G-code position only (nothing moves, its extrusion is not
//   made up later); the first move after it goes straight from where the machine is. Marlin's
//   own M486 (T/S/P/C, the parser gives the same forms) names an object by its index.
// Travel limits act only on homed axes: before G28 a move of an unhomed X/Y/Z axis is refused with
// a clear error (Klipper's "Must home axis first"; on a delta every tower must be homed), unless
// config.allow_moves_before_homing (then the machine starts homed, the old behaviour). E needs no
// homing.
// Extrusion is bounded as Klipper bounds it (config.max_extrude_only_distance_mm,
// max_extrude_cross_section_mm2), and a machine with a hotend says through set_extrude_guard()
// whether the extruder may move at all (a cold hotend: Klipper's "Extrude below minimum temp",
// Marlin's cold extrusion prevention); a move or retraction that moves E is refused whole then.
// Every command is validated completely before anything changes: a rejected command (unreachable
// or out-of-travel target, bad arc, unsupported form) returns an Error with the source location
// and leaves the state and the planner untouched. Commands that are not about motion (heaters,
// fans, messages) return Ok and are counted in ignored().
// Owner: the planner thread.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "gcode/command.hpp"
#include "planner/kinematics.hpp"
#include "planner/lookahead.hpp"
#include "planner/object_labels.hpp"

namespace feedloop::planner {

// How E is interpreted: following G90/G91 (Marlin resets to this on G90/G91), or forced by M82/M83.
enum class EMode { follow_xyz, absolute, relative };

struct MachineState {
  Vec4 logical_mm{};   // positions as the G-code sees them (after G92)
  Vec4 machine_mm{};   // planner coordinates; E accumulates the flow-scaled extrusion
  Vec4 offset_mm{};    // G92: machine = logical + offset (X Y Z); E is tracked separately
  bool relative_xyz = false;
  EMode e_mode = EMode::follow_xyz;
  double unit_mm = 1.0;           // 25.4 after G20
  double feedrate_mm_s = 25.0;    // last F
  double speed_factor = 1.0;      // M220 S / 100
  double saved_speed_factor = 1.0;  // M220 B backs speed_factor up here, M220 R restores it
  double flow_factor = 1.0;       // M221 S / 100
  double print_accel_mm_s2 = 0.0, retract_accel_mm_s2 = 0.0, travel_accel_mm_s2 = 0.0;  // M204
  Vec4 max_axis_velocity_mm_s{};  // M203
  Vec4 max_axis_accel_mm_s2{};    // M201
  Vec4 jerk_mm_s{};               // M205 X Y Z E, recorded only
  double junction_deviation_mm = 0.0;
  bool retracted = false;         // G10 active
  double hop_mm = 0.0;            // Z lift applied by G10
  double retract_length_mm = 0.0, retract_velocity_mm_s = 0.0, retract_zlift_mm = 0.0;
  double unretract_extra_mm = 0.0, unretract_velocity_mm_s = 0.0;
  bool homed[3] = {false, false, false};  // X Y Z since the last G28 (and no M18/M84 since)
  double pressure_advance_s = 0.0;        // M900 K / SET_PRESSURE_ADVANCE ADVANCE
  double pressure_advance_smooth_time_s = 0.040;  // SET_PRESSURE_ADVANCE SMOOTH_TIME
  bool e_relative() const { return e_mode == EMode::relative || (e_mode == EMode::follow_xyz && relative_xyz); }
};

class Interpreter {
 public:
  Interpreter(const PlannerConfig& config, const Kinematics& kinematics, Planner& planner);

  Status execute(const gcode::Command& cmd);
  const MachineState& state() const { return st_; }
  uint64_t ignored() const { return ignored_; }
  uint64_t moves() const { return moves_; }
  // The object labels, and the G0-G3/G10/G11 lines skipped because their object is excluded.
  const ObjectLabels& objects() const { return objects_; }
  uint64_t skipped_lines() const { return skipped_lines_; }
  // The homed axes as lower-case letters in xyz order ("" .. "xyz"): out holds 4 chars.
  void homed_axes(char out[4]) const;
  // G28 through the endstops (the executor homed the axes, engine/motion_executor.cpp): the axes
  // in `axes` (X Y Z) are homed at machine position at_mm (their G92 offsets, and a Z hop when Z is
  // homed, cleared; logical = machine), and the planner continues from there; an axis not in
  // `axes` moves to at_mm in its own frame (CoreXY: the homing moved it). The planner must hold
  // no moves.
  void set_homed(const bool axes[3], const Vec4& at_mm);
  // A flush stopped the motion short of what was planned (engine::Machine::flush): the machine is
  // at machine position at_mm (X Y Z E, planner coordinates). The logical position follows it
  // (the G92 offsets, a Z hop and the modes are kept; no object is current any more); the planner
  // continues from there. The planner must hold no moves.
  void set_machine_position(const Vec4& at_mm);
  // A failed homing: the axes in `axes` are no longer homed.
  void set_unhomed(const bool axes[3]);
  // Asked before any move that moves E: why the extruder may not move now ("" when it may).
  using ExtrudeGuard = std::function<std::string()>;
  void set_extrude_guard(ExtrudeGuard guard) { extrude_guard_ = std::move(guard); }

 private:
  Status linear(const gcode::Command& c);
  Status arc(const gcode::Command& c, bool clockwise);
  Status home(const gcode::Command& c);
  Status retract(const gcode::Command& c, bool recover);
  Status set_position(const gcode::Command& c);
  Status motors_off(const gcode::Command& c);
  // Error unless every X/Y/Z axis that moves between from and to is homed.
  Status check_homed(const Vec4& from, const Vec4& to, const gcode::Command& c) const;
  Status limits(const gcode::Command& c);
  Status pressure_advance(const gcode::Command& c);
  Status object_label(const gcode::Command& c);
  // A G0-G3 line of an excluded object: the G-code position follows it, nothing moves.
  Status skip_excluded(const gcode::Command& c);
  // Logical target of a G0-G3 line (unchanged axes stay), and its machine coordinates.
  Vec4 logical_target(const gcode::Command& c) const;
  Vec4 to_machine(const Vec4& logical) const;
  double accel_for(const Vec4& from, const Vec4& to) const;
  Status check(const Vec4& from, const Vec4& to, const gcode::Command& c) const;
  // The extrusion bounds and the guard, for a move from `from` to `to` (machine coordinates).
  Status check_extrusion(const Vec4& from, const Vec4& to, const gcode::Command& c) const;
  void push(const Vec4& to, double velocity_mm_s, double accel_mm_s2, int line);
  static Status fail(const gcode::Command& c, std::string message);

  PlannerConfig cfg_;
  const Kinematics& kin_;
  Planner& planner_;
  MachineState st_;
  ObjectLabels objects_;
  ExtrudeGuard extrude_guard_;
  uint64_t ignored_ = 0, moves_ = 0, skipped_lines_ = 0;
};

}  // namespace feedloop::planner
