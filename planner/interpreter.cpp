// G-code interpretation (see interpreter.hpp).
#include "planner/interpreter.hpp"

#include <algorithm>  // clamp
#include <cmath>    // isfinite, abs
#include <cstdio>   // snprintf
#include <numbers>  // pi
#include <utility>  // std::move

#include "planner/arc.hpp"
#include "planner/pressure_advance.hpp"

namespace feedloop::planner {

namespace {
constexpr char kAxisLetter[kAxes] = {'X', 'Y', 'Z', 'E'};
constexpr double kMaxArcSegments = 1e6;

bool all_finite(const gcode::Command& c) {
  for (char p = 'A'; p <= 'Z'; ++p) {
    if (c.has(p) && !std::isfinite(c.get(p))) return false;
  }
  return true;
}
}  // namespace

Interpreter::Interpreter(const PlannerConfig& config, const Kinematics& kinematics, Planner& planner)
    : cfg_(config), kin_(kinematics), planner_(planner) {
  st_.machine_mm = planner.position();
  st_.logical_mm = st_.machine_mm;
  st_.print_accel_mm_s2 = config.print_accel_mm_s2;
  st_.retract_accel_mm_s2 = config.retract_accel_mm_s2;
  st_.travel_accel_mm_s2 = config.travel_accel_mm_s2;
  st_.max_axis_velocity_mm_s = config.max_axis_velocity_mm_s;
  st_.max_axis_accel_mm_s2 = config.max_axis_accel_mm_s2;
  st_.junction_deviation_mm = planner.junction_deviation();
  st_.pressure_advance_s = config.pressure_advance_s;
  st_.pressure_advance_smooth_time_s = config.pressure_advance_smooth_time_s;
  st_.retract_length_mm = config.retract_length_mm;
  st_.retract_velocity_mm_s = config.retract_velocity_mm_s;
  st_.retract_zlift_mm = config.retract_zlift_mm;
  st_.unretract_extra_mm = config.unretract_extra_mm;
  st_.unretract_velocity_mm_s = config.unretract_velocity_mm_s;
  for (bool& h : st_.homed) h = config.allow_moves_before_homing;
}

void Interpreter::homed_axes(char out[4]) const {
  int n = 0;
  for (int i = 0; i < 3; ++i)
    if (st_.homed[i]) out[n++] = static_cast<char>('x' + i);
  out[n] = '\0';
}

Status Interpreter::check_homed(const Vec4& from, const Vec4& to, const gcode::Command& c) const {
  if (cfg_.allow_moves_before_homing) return {};
  const bool delta = cfg_.kinematics == KinematicsKind::delta;
  const bool xyz = from[0] != to[0] || from[1] != to[1] || from[2] != to[2];
  std::string missing;
  for (int i = 0; i < 3; ++i) {
    // A delta's carriages all move for any XYZ move: every tower must be homed.
    const bool moves = delta ? xyz : from[i] != to[i];
    if (moves && !st_.homed[i]) missing += kAxisLetter[i];
  }
  if (missing.empty()) return {};
  return fail(c, "move rejected, nothing executed: Must home axis first (" + missing +
                     " not homed; send G28, or set planner.allow_moves_before_homing: true)");
}

Status Interpreter::fail(const gcode::Command& c, std::string message) {
  char head[32];
  std::snprintf(head, sizeof head, "%c%d: ", c.letter, c.code);
  return Error{head + std::move(message), c.where};
}

Status Interpreter::execute(const gcode::Command& c) {
  if (c.empty()) return {};
  if (!all_finite(c)) return fail(c, "parameter is not a finite number");
  if (c.letter == 'G') {
    switch (c.code) {
      case 0:
      case 1:
        return objects_.excluding() ? skip_excluded(c) : linear(c);
      case 2:
        return objects_.excluding() ? skip_excluded(c) : arc(c, true);
      case 3:
        return objects_.excluding() ? skip_excluded(c) : arc(c, false);
      case 4: {
        const double s = c.has('S') ? c.get('S') : c.get('P') / 1000.0;
        if (s < 0.0) return fail(c, "dwell time must be >= 0");
        planner_.dwell(s, c.where.line);
        return {};
      }
      case 10:
      case 11:
        if (objects_.excluding() && !c.has('L') && !c.has('P')) {
          ++skipped_lines_;  // the excluded object's retraction: neither made nor recovered
          return {};
        }
        return retract(c, c.code == 11);
      case 17: return {};
      case 18: case 19: return fail(c, "only the XY plane (G17) is supported for arcs");
      case 20: st_.unit_mm = 25.4; return {};
      case 21: st_.unit_mm = 1.0; return {};
      case 28: return home(c);
      case 90: st_.relative_xyz = false; st_.e_mode = EMode::follow_xyz; return {};
      case 91: st_.relative_xyz = true; st_.e_mode = EMode::follow_xyz; return {};
      case 92: return set_position(c);
      default: ++ignored_; return {};
    }
  }
  if (c.letter == 'M') {
    switch (c.code) {
      case 82: st_.e_mode = EMode::absolute; return {};
      case 83: st_.e_mode = EMode::relative; return {};
      case 220:
        // Marlin's M220 (gcode/config/M220.cpp): B backs the factor up, R restores it, then S.
        if (c.has('S') && !(c.get('S') > 0.0)) return fail(c, "speed factor S must be > 0 %");
        if (c.has('B')) st_.saved_speed_factor = st_.speed_factor;
        if (c.has('R')) st_.speed_factor = st_.saved_speed_factor;
        if (c.has('S')) st_.speed_factor = c.get('S') / 100.0;
        return {};
      case 221:
        if (c.has('S')) {
          if (!(c.get('S') >= 0.0)) return fail(c, "flow factor S must be >= 0 %");
          st_.flow_factor = c.get('S') / 100.0;
        }
        return {};
      case 400: planner_.wait_for_moves(c.where.line); return {};
      case 18: case 84: return motors_off(c);
      case 201: case 203: case 204: case 205: case 207: case 208: return limits(c);
      case 900:
        return pressure_advance(c);
      case 486:
        if (c.subcode >= gcode::kObjectDefine && c.subcode <= gcode::kObjectName && !c.unknown)
          return object_label(c);
        ++ignored_;
        return {};
      default: ++ignored_; return {};
    }
  }
  // Tool selection: the planner drives one extruder. Another tool's lines would print with the
  // wrong filament (Marlin answers "Invalid extruder" and prints on): refused, nothing changed.
  if (c.letter == 'T')
    return c.code == 0 ? Status{} : fail(c, "this machine has one extruder (T0); nothing changed");
  ++ignored_;
  return {};
}

Vec4 Interpreter::logical_target(const gcode::Command& c) const {
  Vec4 t = st_.logical_mm;
  for (int i = 0; i < kAxes; ++i) {
    if (!c.has(kAxisLetter[i])) continue;
    const double v = c.get(kAxisLetter[i]) * st_.unit_mm;
    const bool rel = i == kE ? st_.e_relative() : st_.relative_xyz;
    t[i] = rel ? st_.logical_mm[i] + v : v;
  }
  return t;
}

Vec4 Interpreter::to_machine(const Vec4& logical) const {
  Vec4 m;
  for (int i = 0; i < 3; ++i) m[i] = logical[i] + st_.offset_mm[i];
  m[kZ] += st_.hop_mm;
  m[kE] = st_.machine_mm[kE] + (logical[kE] - st_.logical_mm[kE]) * st_.flow_factor;
  return m;
}

double Interpreter::accel_for(const Vec4& from, const Vec4& to) const {
  const bool xyz = from[0] != to[0] || from[1] != to[1] || from[2] != to[2];
  const bool e = from[kE] != to[kE];
  if (!xyz) return st_.retract_accel_mm_s2;  // E-only (Marlin: retract_acceleration)
  return e ? st_.print_accel_mm_s2 : st_.travel_accel_mm_s2;
}

Status Interpreter::check_extrusion(const Vec4& from, const Vec4& to,
                                    const gcode::Command& c) const {
  const double de_mm = to[kE] - from[kE];
  if (de_mm == 0.0) return {};
  if (extrude_guard_) {
    const std::string why = extrude_guard_();
    if (!why.empty()) return fail(c, "move rejected, nothing executed: " + why);
  }
  const double dx = to[0] - from[0], dy = to[1] - from[1], dz = to[2] - from[2];
  const double travel_mm = std::sqrt(dx * dx + dy * dy + dz * dz);
  char buf[200];
  if (travel_mm == 0.0) {
    const double limit_mm = cfg_.max_extrude_only_distance_mm;
    if (limit_mm > 0.0 && std::abs(de_mm) > limit_mm) {
      std::snprintf(buf, sizeof buf,
                    "move rejected, nothing executed: extrude-only move too long (%.3f mm vs "
                    "%.3f mm; extruder.max_extrude_only_distance)",
                    std::abs(de_mm), limit_mm);
      return fail(c, buf);
    }
    return {};
  }
  // Klipper's check (extras/extruder.py): the track this extrusion per mm of travel would lay,
  // de * filament area / travel, against the bound; an amount under one nozzle's worth passes.
  const double area_mm2 =
      std::numbers::pi / 4.0 * cfg_.filament_diameter_mm * cfg_.filament_diameter_mm;
  const double limit_mm2 = cfg_.max_extrude_cross_section_mm2;
  const double cross_mm2 = de_mm * area_mm2 / travel_mm;
  if (limit_mm2 > 0.0 && cross_mm2 > limit_mm2 &&
      de_mm > cfg_.nozzle_diameter_mm * limit_mm2 / area_mm2) {
    std::snprintf(buf, sizeof buf,
                  "move rejected, nothing executed: move exceeds maximum extrusion (%.3f mm^2 vs "
                  "%.3f mm^2; extruder.max_extrude_cross_section)",
                  cross_mm2, limit_mm2);
    return fail(c, buf);
  }
  return {};
}

Status Interpreter::check(const Vec4& from, const Vec4& to, const gcode::Command& c) const {
  if (Status s = check_extrusion(from, to, c); !s) return s;
  const bool xyz = from[0] != to[0] || from[1] != to[1] || from[2] != to[2];
  if (!xyz) return {};
  if (Status s = check_homed(from, to, c); !s) return s;
  // The start is where the machine is. After a homing through an endstop that may be a few steps
  // past the travel's end (the MCU stops the motor sample_count samples after the trigger; Klipper
  // also sets that halt position): on a Cartesian machine the start, and an axis the move leaves
  // where it is, are taken on the box's face for the check (Klipper's cartesian.py checks the end
  // of the axes that move only).
  Vec3 a{from[0], from[1], from[2]}, b{to[0], to[1], to[2]};
  if (cfg_.kinematics != KinematicsKind::delta)
    for (size_t i = 0; i < 3; ++i) {
      const bool still = b[i] == a[i];
      a[i] = std::clamp(a[i], cfg_.min_position_mm[i], cfg_.max_position_mm[i]);
      if (still) b[i] = a[i];
    }
  Status s = kin_.check_segment(a, b);
  if (!s) return fail(c, "move rejected, nothing executed: " + s.error().message);
  return {};
}

void Interpreter::push(const Vec4& to, double velocity_mm_s, double accel_mm_s2, int line) {
  planner_.add_move({to, velocity_mm_s, accel_mm_s2, line});
  ++moves_;
}

Status Interpreter::linear(const gcode::Command& c) {
  double feed = st_.feedrate_mm_s;
  if (c.has('F')) {
    if (!(c.get('F') > 0.0)) return fail(c, "feedrate F must be > 0");
    feed = c.get('F') * st_.unit_mm / 60.0;
  }
  const Vec4 logical = logical_target(c);
  const Vec4 to = to_machine(logical);
  if (Status s = check(st_.machine_mm, to, c); !s) return s;
  // commit
  st_.feedrate_mm_s = feed;
  push(to, feed * st_.speed_factor, accel_for(st_.machine_mm, to), c.where.line);
  st_.logical_mm = logical;
  st_.machine_mm = to;
  return {};
}

Status Interpreter::arc(const gcode::Command& c, bool clockwise) {
  double feed = st_.feedrate_mm_s;
  if (c.has('F')) {
    if (!(c.get('F') > 0.0)) return fail(c, "feedrate F must be > 0");
    feed = c.get('F') * st_.unit_mm / 60.0;
  }
  const bool use_r = c.has('R');
  if (!use_r && !c.has('I') && !c.has('J')) return fail(c, "arc needs I/J or R");
  if (use_r && (c.has('I') || c.has('J'))) return fail(c, "arc takes either I/J or R, not both");
  const Vec4 logical = logical_target(c);
  const Vec4 to = to_machine(logical);
  const Vec4 from = st_.machine_mm;
  Result<ArcPlan> plan = plan_arc(from, to, clockwise, use_r, c.get('I') * st_.unit_mm, c.get('J') * st_.unit_mm,
                                  c.get('R') * st_.unit_mm, cfg_.arc_tolerance_mm);
  if (!plan) return fail(c, plan.error().message);
  if (plan->segments > kMaxArcSegments) return fail(c, "arc needs too many segments for the tolerance");
  // Check every segment before queueing any.
  Vec4 a = from;
  for (int k = 1; k <= plan->segments; ++k) {
    const Vec4 b = arc_point(*plan, from, to, k);
    if (Status s = check(a, b, c); !s) return s;
    a = b;
  }
  st_.feedrate_mm_s = feed;
  const double accel = accel_for(from, to);
  for (int k = 1; k <= plan->segments; ++k) push(arc_point(*plan, from, to, k), feed * st_.speed_factor, accel, c.where.line);
  st_.logical_mm = logical;
  st_.machine_mm = to;
  return {};
}

Status Interpreter::skip_excluded(const gcode::Command& c) {
  double feed = st_.feedrate_mm_s;
  if (c.has('F')) {
    if (!(c.get('F') > 0.0)) return fail(c, "feedrate F must be > 0");
    feed = c.get('F') * st_.unit_mm / 60.0;
  }
  st_.feedrate_mm_s = feed;
  // machine_mm stays where the machine is; the next kept move starts there, and its E delta
  // counts from this logical E (to_machine), so the skipped extrusion is dropped.
  st_.logical_mm = logical_target(c);
  ++skipped_lines_;
  return {};
}

Status Interpreter::object_label(const gcode::Command& c) {
  const std::string& name = c.text;
  switch (c.subcode) {
    case gcode::kObjectDefine:
      if (c.has('R')) {
        objects_.reset_all();
        return {};
      }
      if (!objects_.define(name)) return fail(c, "too many objects (at most 1024 defined)");
      return {};
    case gcode::kObjectStart:
      if (!objects_.start(objects_.resolve(name)))
        return fail(c, "too many objects (at most 1024 defined)");
      return {};
    case gcode::kObjectEnd:
      objects_.end();
      return {};
    case gcode::kObjectName:
      // RepRapFirmware's M486 S<i> A"name" starts object i too; Marlin's M486 A<name> names the
      // object its S line started. A name another object has keeps this one's index (no slicer
      // writes two objects of one name: PrusaSlicer's hold the id and the copy).
      if (c.has('S')) {
        const std::string index = ObjectLabels::index_name(c.get('S'));
        if (!objects_.start(objects_.resolve(index)))
          return fail(c, "too many objects (at most 1024 defined)");
      }
      // A name for no object (a stray name line) is nothing to do, as Marlin ignores the A.
      if (objects_.current().empty())
        ++ignored_;
      else
        objects_.name_current(name);
      return {};
    default:  // kObjectExclude
      if (c.has('R')) {
        objects_.reset_excluded();
        return {};
      }
      if (c.has('C')) {
        if (objects_.current().empty())
          return fail(
              c,
              "no object is being printed (EXCLUDE_OBJECT CURRENT=1, M486 C: the current object)");
        objects_.exclude(objects_.current());
        return {};
      }
      if (name.empty()) return {};  // the list: the status reports it
      if (!objects_.exclude(objects_.resolve(name)))
        return fail(c, "too many objects (at most 1024 excluded)");
      return {};
  }
}

Status Interpreter::home(const gcode::Command& c) {
  const bool any = c.has('X') || c.has('Y') || c.has('Z');
  Vec4 to = st_.machine_mm;
  bool homed[3];
  for (int i = 0; i < 3; ++i) {
    homed[i] = !any || c.has(kAxisLetter[i]);
    if (homed[i]) to[i] = cfg_.home_position_mm[i];
  }
  // The homing move itself needs no homed axes; the target must still be reachable.
  if (Status s = kin_.check_segment({st_.machine_mm[0], st_.machine_mm[1], st_.machine_mm[2]}, {to[0], to[1], to[2]}); !s)
    return fail(c, "move rejected, nothing executed: " + s.error().message);
  push(to, cfg_.homing_velocity_mm_s, st_.travel_accel_mm_s2, c.where.line);
  planner_.mark_homed(c.where.line);
  // A delta homes its three towers together (Klipper: G28 on a delta always homes all).
  const bool delta = cfg_.kinematics == KinematicsKind::delta;
  for (int i = 0; i < 3; ++i) st_.homed[i] = st_.homed[i] || homed[i] || delta;
  // After homing, logical == machine on the homed axes (G92 offsets of those axes are cleared).
  for (int i = 0; i < 3; ++i) {
    if (!homed[i]) continue;
    st_.offset_mm[i] = 0.0;
    st_.logical_mm[i] = to[i];
  }
  if (homed[kZ]) st_.hop_mm = 0.0;
  st_.machine_mm = to;
  return {};
}

void Interpreter::set_homed(const bool axes[3], const Vec4& at_mm) {
  const bool delta = cfg_.kinematics == KinematicsKind::delta;
  for (int i = 0; i < 3; ++i) {
    if (!axes[i] && !delta) {
      // An axis the homing moved without homing it (CoreXY: the relayed overshoot of the second
      // motor) keeps its frame and moves by as much.
      const size_t is = static_cast<size_t>(i);
      st_.logical_mm[is] += at_mm[is] - st_.machine_mm[is];
      st_.machine_mm[is] = at_mm[is];
      continue;
    }
    st_.homed[i] = true;
    st_.offset_mm[i] = 0.0;
    st_.machine_mm[i] = at_mm[static_cast<size_t>(i)];
    st_.logical_mm[i] = at_mm[static_cast<size_t>(i)];
  }
  if (axes[kZ] || delta) st_.hop_mm = 0.0;
  planner_.set_position(st_.machine_mm);
}

void Interpreter::set_machine_position(const Vec4& at_mm) {
  for (int i = 0; i < 3; ++i) {
    st_.machine_mm[i] = at_mm[static_cast<size_t>(i)];
    st_.logical_mm[i] = at_mm[static_cast<size_t>(i)] - st_.offset_mm[i] - (i == kZ ? st_.hop_mm : 0.0);
  }
  // E: the logical E moves with the machine's by the flow factor (to_machine's inverse).
  const double de_mm = at_mm[kE] - st_.machine_mm[kE];
  st_.logical_mm[kE] += st_.flow_factor > 0.0 ? de_mm / st_.flow_factor : de_mm;
  st_.machine_mm[kE] = at_mm[kE];
  planner_.set_position(st_.machine_mm);
  // The flush ended the file's object too: a console move after a cancel inside an excluded
  // object is not skipped.
  objects_.end();
}

void Interpreter::set_unhomed(const bool axes[3]) {
  if (cfg_.allow_moves_before_homing) return;
  const bool delta = cfg_.kinematics == KinematicsKind::delta;
  for (int i = 0; i < 3; ++i)
    if (axes[i] || delta) st_.homed[i] = false;
}

Status Interpreter::retract(const gcode::Command& c, bool recover) {
  if (c.has('L')) return fail(c, "G10 L (tool/work offsets) is not supported; G10 alone retracts");
  if (c.has('P')) return {};  // the temperature form (G10 P0 S210): the heaters', nothing moves
  if (!recover) {
    if (st_.retracted) return {};
    Vec4 e_to = st_.machine_mm;
    e_to[kE] -= st_.retract_length_mm;
    Vec4 z_to = e_to;
    z_to[kZ] += st_.retract_zlift_mm;
    if (Status s = check_extrusion(st_.machine_mm, e_to, c); !s) return s;
    if (Status s = check(e_to, z_to, c); !s) return s;
    push(e_to, st_.retract_velocity_mm_s, st_.retract_accel_mm_s2, c.where.line);
    if (st_.retract_zlift_mm > 0.0) push(z_to, st_.max_axis_velocity_mm_s[kZ], st_.travel_accel_mm_s2, c.where.line);
    st_.hop_mm = st_.retract_zlift_mm;
    st_.retracted = true;
    st_.machine_mm = z_to;
    return {};
  }
  if (!st_.retracted) return {};
  Vec4 z_to = st_.machine_mm;
  z_to[kZ] -= st_.hop_mm;
  if (Status s = check(st_.machine_mm, z_to, c); !s) return s;
  Vec4 e_to = z_to;
  e_to[kE] += st_.retract_length_mm + st_.unretract_extra_mm;
  if (Status s = check_extrusion(z_to, e_to, c); !s) return s;
  if (st_.hop_mm > 0.0) push(z_to, st_.max_axis_velocity_mm_s[kZ], st_.travel_accel_mm_s2, c.where.line);
  push(e_to, st_.unretract_velocity_mm_s, st_.retract_accel_mm_s2, c.where.line);
  st_.hop_mm = 0.0;
  st_.retracted = false;
  st_.machine_mm = e_to;
  return {};
}

Status Interpreter::set_position(const gcode::Command& c) {
  for (int i = 0; i < kAxes; ++i) {
    if (!c.has(kAxisLetter[i])) continue;
    const double v = c.get(kAxisLetter[i]) * st_.unit_mm;
    // Inside an excluded object the machine did not follow the G-code: the offset counts from
    // where the G-code is (machine = logical + offset + hop elsewhere).
    if (i < 3)
      st_.offset_mm[i] = objects_.excluding() ? st_.logical_mm[i] + st_.offset_mm[i] - v
                                              : st_.machine_mm[i] - st_.hop_mm * (i == kZ) - v;
    st_.logical_mm[i] = v;  // E: the machine E is unchanged, only the logical origin moves
  }
  return {};
}

// M18/M84: without S, the motors are switched off and their axes lose their position: Marlin
// (gcode/control/M18_M84.cpp) disables the steppers and marks the axes untrusted, so they must be
// homed again. Axis letters select the axes (a delta's towers go together); M84 S<seconds> only
// sets the idle timeout and changes nothing here. E needs no homing.
Status Interpreter::motors_off(const gcode::Command& c) {
  if (c.has('S') && !c.has('X') && !c.has('Y') && !c.has('Z') && !c.has('E')) return {};
  if (cfg_.allow_moves_before_homing) return {};  // the old behaviour: position kept
  const bool any = c.has('X') || c.has('Y') || c.has('Z');
  const bool only_e = c.has('E') && !any;
  if (only_e) return {};
  const bool delta = cfg_.kinematics == KinematicsKind::delta;
  for (int i = 0; i < 3; ++i)
    if (!any || delta || c.has(kAxisLetter[i])) st_.homed[i] = false;
  return {};
}

// M900 K<k> (Marlin's linear advance, gcode/feature/advance/M900.cpp: K in 0..10, 0 = off) and
// Klipper's SET_PRESSURE_ADVANCE ADVANCE=<k> SMOOTH_TIME=<s> (the parser hands it over as M900
// with text "SET_PRESSURE_ADVANCE", K = ADVANCE, S = SMOOTH_TIME; Klipper's extruder.py bounds
// SMOOTH_TIME to 0.200 s). Checked completely before anything changes.
Status Interpreter::pressure_advance(const gcode::Command& c) {
  const bool klipper = c.text == "SET_PRESSURE_ADVANCE";
  auto bad = [&](const char* marlin, const char* klipper_msg) -> Status {
    if (!klipper) return fail(c, marlin);
    return Error{std::string("SET_PRESSURE_ADVANCE: ") + klipper_msg, c.where};
  };
  double k = st_.pressure_advance_s, smooth = st_.pressure_advance_smooth_time_s;
  if (c.has('K')) {
    k = c.get('K', -1.0);
    if (!std::isfinite(k) || k < 0.0 || k > PressureAdvanceLimits::kMaxAdvance_s)
      return bad("K must be in [0, 10] s (0 switches the advance off)",
                 "ADVANCE must be in [0, 10] s (0 switches the advance off)");
  }
  if (klipper && c.has('S')) {
    smooth = c.get('S', -1.0);
    if (!std::isfinite(smooth) || !(smooth > 0.0) ||
        smooth > PressureAdvanceLimits::kMaxSmoothTime_s)
      return bad("", "SMOOTH_TIME must be in (0, 0.200] s");
  }
  if (!klipper && c.has('T') && c.get('T') != 0.0) return fail(c, "there is one extruder (T0)");
  st_.pressure_advance_s = k;
  st_.pressure_advance_smooth_time_s = smooth;
  planner_.set_pressure_advance(k, smooth);
  return {};
}

Status Interpreter::limits(const gcode::Command& c) {
  const double u = st_.unit_mm;
  auto positive = [&](char p) { return !c.has(p) || c.get(p) > 0.0; };
  switch (c.code) {
    case 201:
    case 203: {
      for (int i = 0; i < kAxes; ++i) {
        if (!positive(kAxisLetter[i])) return fail(c, std::string("limit ") + kAxisLetter[i] + " must be > 0");
      }
      Vec4& target = c.code == 201 ? st_.max_axis_accel_mm_s2 : st_.max_axis_velocity_mm_s;
      for (int i = 0; i < kAxes; ++i) {
        if (c.has(kAxisLetter[i])) target[i] = c.get(kAxisLetter[i]) * u;
      }
      planner_.set_axis_limits(st_.max_axis_velocity_mm_s, st_.max_axis_accel_mm_s2);
      return {};
    }
    case 204:
      if (!positive('P') || !positive('R') || !positive('T') || !positive('S')) return fail(c, "accelerations must be > 0");
      if (c.has('S')) st_.print_accel_mm_s2 = st_.travel_accel_mm_s2 = c.get('S') * u;  // legacy: both
      if (c.has('P')) st_.print_accel_mm_s2 = c.get('P') * u;
      if (c.has('R')) st_.retract_accel_mm_s2 = c.get('R') * u;
      if (c.has('T')) st_.travel_accel_mm_s2 = c.get('T') * u;
      return {};
    case 205:
      if (c.has('J')) {
        if (!(c.get('J') > 0.0)) return fail(c, "junction deviation J must be > 0");
        st_.junction_deviation_mm = c.get('J') * u;
        planner_.set_junction_deviation(st_.junction_deviation_mm);
      }
      for (int i = 0; i < kAxes; ++i) {
        if (c.has(kAxisLetter[i])) st_.jerk_mm_s[i] = c.get(kAxisLetter[i]) * u;
      }
      return {};
    case 207:
      if (c.has('S') && c.get('S') < 0.0) return fail(c, "retract length must be >= 0");
      if (!positive('F')) return fail(c, "retract feedrate must be > 0");
      if (c.has('S')) st_.retract_length_mm = c.get('S') * u;
      if (c.has('F')) st_.retract_velocity_mm_s = c.get('F') * u / 60.0;
      if (c.has('Z')) st_.retract_zlift_mm = std::abs(c.get('Z') * u);
      return {};
    case 208:
      if (!positive('F')) return fail(c, "recover feedrate must be > 0");
      if (c.has('S')) st_.unretract_extra_mm = c.get('S') * u;
      if (c.has('F')) st_.unretract_velocity_mm_s = c.get('F') * u / 60.0;
      return {};
    default: return {};
  }
}

}  // namespace feedloop::planner
