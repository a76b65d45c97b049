// Config sections `axes` and `delta` (geometry), and the axis sets each kinematics needs.
#include "config/enum_names.hpp"
#include "config/sections.hpp"

#include <cmath>  // isfinite, round

namespace feedloop::config::detail {

const std::vector<std::string>& required_axes(Kinematics k) {
  static const std::vector<std::string> xyz = {"x", "y", "z"};
  static const std::vector<std::string> abc = {"A", "B", "C"};
  return k == Kinematics::delta ? abc : xyz;
}

const std::vector<std::string>& allowed_axes(Kinematics k) {
  static const std::vector<std::string> xyze = {"x", "y", "z", "e"};
  static const std::vector<std::string> abce = {"A", "B", "C", "e"};
  return k == Kinematics::delta ? abce : xyze;
}

namespace {
// Plausibility bounds (docs/decisions-config.md): values beyond them are typing errors, and some
// of them would make the daemon allocate without bound (steps/mm x speed = steps per second).
constexpr double kMaxStepsPerMm = 1e6;        // 256 microsteps x 400 steps/turn on a 0.1 mm lead
constexpr double kMaxStepRateHz = 4e6;        // a step every 0.25 us: beyond any MCU step timer
constexpr double kMaxAxisVelocityMmS = 10000; // 10 m/s
constexpr double kMaxAxisAccelMmS2 = 1e6;     // 100 g
// The MCU confirms a trigger after 4 samples 50 us apart (drivers/host/homing.hpp): the carriage
// overshoots the trip point by homing_speed x 200 us before its steps stop.
constexpr double kEndstopConfirmS = 4 * 50e-6;

// axes.<name>.homing (Klipper's stepper homing keys, docs/homing.md). Defaults like Klipper's:
// position_endstop at the switch's end of the travel, homing_speed 5 mm/s, second_homing_speed
// half of it, retract 5 mm, the approach up to 1.5 x the travel range. Every check is reported at
// the offending key (file:line:col).
void read_homing(MapReader& a, AxisConfig& axis, Diagnostics& diag) {
  MapReader h = a.sub("homing");
  HomingConfig c;
  const bool has_dir = h.choice("direction", c.direction, endstop_side_names());
  const bool has_pos = h.number("position_endstop_mm", c.position_endstop_mm, Range::any());
  // Klipper infers homing_positive_dir from a position_endstop at position_max.
  if (!has_dir && has_pos && c.position_endstop_mm == axis.max_mm) c.direction = EndstopSide::max;
  if (!has_pos) c.position_endstop_mm = c.direction == EndstopSide::min ? axis.min_mm : axis.max_mm;
  const bool has_speed = h.number("homing_speed_mm_s", c.homing_speed_mm_s, Range::positive());
  if (!h.number("second_homing_speed_mm_s", c.second_homing_speed_mm_s, Range::positive()))
    c.second_homing_speed_mm_s = c.homing_speed_mm_s / 2.0;
  h.number("retract_dist_mm", c.retract_dist_mm, Range::non_negative());
  h.boolean("index", c.index);
  double index_pos = 0.0;
  if (h.number("index_position_mm", index_pos, Range::any())) c.index_position_mm = index_pos;
  h.boolean("stall", c.stall);
  h.number("stall_threshold_mm", c.stall_threshold_mm, Range::open_closed(0.0, 5.0));
  if (c.stall && !axis.encoder)
    diag.add(h.key_mark("stall"), h.path() + ".stall: stall homing needs " + a.path() +
                                      ".encoder (the MCU compares its counts with the steps)");
  if (c.stall && c.index)
    diag.add(h.key_mark("stall"), h.path() + ": stall and index homing do not go together");
  if (c.index && !(axis.encoder && axis.encoder->index_period_mm > 0.0))
    diag.add(h.key_mark("index"), h.path() + ".index: encoder-index homing needs " + a.path() +
                                      ".encoder.index_period_mm (the encoder's index marks)");
  const double range_mm = axis.max_mm - axis.min_mm;
  const bool has_travel = h.number("max_travel_mm", c.max_travel_mm, Range::positive());
  if (!has_travel) c.max_travel_mm = std::isfinite(range_mm) ? 1.5 * range_mm : 0.0;
  if (!std::isfinite(axis.min_mm) || !std::isfinite(axis.max_mm)) {
    diag.add(h.mark(), h.path() + ": homing needs the axis's travel (min_mm and max_mm)");
  } else {
    if (!(c.position_endstop_mm >= axis.min_mm && c.position_endstop_mm <= axis.max_mm))
      diag.add(h.key_mark("position_endstop_mm"),
               h.path() + ".position_endstop_mm " + format_number(c.position_endstop_mm) +
                   " mm must lie within the travel " + format_number(axis.min_mm) + " .. " +
                   format_number(axis.max_mm) +
                   " mm (Klipper: position_endstop in position_min .. position_max)");
    if (has_travel && c.max_travel_mm > 10.0 * range_mm)
      diag.add(h.key_mark("max_travel_mm"),
               h.path() + ".max_travel_mm " + format_number(c.max_travel_mm) +
                   " mm is not plausible (at most 10 x the travel range, " +
                   format_number(10.0 * range_mm) + " mm)");
  }
  if (has_speed && c.homing_speed_mm_s > axis.max_velocity_mm_s)
    diag.add(h.key_mark("homing_speed_mm_s"), h.path() + ".homing_speed_mm_s " +
                                                  format_number(c.homing_speed_mm_s) +
                                                  " mm/s is above the axis's max_velocity_mm_s " +
                                                  format_number(axis.max_velocity_mm_s));
  if (c.second_homing_speed_mm_s > c.homing_speed_mm_s)
    diag.add(h.key_mark("second_homing_speed_mm_s"),
             h.path() + ".second_homing_speed_mm_s " + format_number(c.second_homing_speed_mm_s) +
                 " mm/s is above homing_speed_mm_s " + format_number(c.homing_speed_mm_s) +
                 " (the second touch is the slow one)");
  if (c.retract_dist_mm > 0.0 && c.homing_speed_mm_s * kEndstopConfirmS >= c.retract_dist_mm)
    diag.add(h.key_mark(has_speed ? "homing_speed_mm_s" : "retract_dist_mm"),
             h.path() + ": homing_speed_mm_s " + format_number(c.homing_speed_mm_s) +
                 " mm/s overshoots the trip point by " +
                 format_number(std::round(c.homing_speed_mm_s * kEndstopConfirmS * 1e6) / 1e6) +
                 " mm before the MCU confirms it, more than retract_dist_mm " +
                 format_number(c.retract_dist_mm));
  if (std::isfinite(range_mm) && c.retract_dist_mm >= range_mm)
    diag.add(h.key_mark("retract_dist_mm"),
             h.path() + ".retract_dist_mm " + format_number(c.retract_dist_mm) +
                 " mm is not less than the travel range " + format_number(range_mm) + " mm");
  h.finish();
  axis.homing = c;
}

// An upper plausibility bound, reported at the value.
void at_most(MapReader& a, Diagnostics& diag, bool present, const char* key, double value, double max,
             const char* unit) {
  if (!present || !(value > max)) return;
  diag.add(a.get(key).Mark(), a.path() + "." + key + " " + format_number(value) + " " + unit +
                                  " is not plausible (at most " + format_number(max) + " " + unit + ")");
}
}  // namespace

void read_axes(MapReader& root, MachineConfig& cfg, Marks& marks, Diagnostics& diag,
               bool kinematics_known) {
  MapReader axes = root.sub("axes", Need::required);
  marks.axes = axes.mark();
  // With a broken kinematics line the axes are still checked, against every possible name.
  static const std::vector<std::string> any_axis = {"x", "y", "z", "A", "B", "C", "e"};
  const std::vector<std::string>& allowed =
      kinematics_known ? allowed_axes(cfg.kinematics) : any_axis;
  const std::string kin = enum_name(kinematics_names(), cfg.kinematics);
  for (const std::string& name : axes.keys()) {
    const YAML::Mark where = axes.key_mark(name);
    MapReader a(axes.get(name), axes.key_path(name), diag, where);
    bool known = false;
    for (const std::string& n : allowed) known = known || n == name;
    if (!known) {
      std::string list;
      for (const std::string& n : allowed) list += (list.empty() ? "" : ", ") + n;
      std::string msg = "axis '" + name + "' does not exist with kinematics " + kin +
                        " (axes: " + list + ")";
      if (const std::string s = closest_match(name, allowed); !s.empty())
        msg += " (did you mean '" + s + "'?)";
      diag.add(where, msg);
      continue;
    }
    marks.axis[name] = where;
    AxisConfig axis;
    axis.name = name;
    const bool is_e = name == "e";
    // Voltage-driven DC motors take no steps (drive: dc_servo).
    const bool has_steps = a.number("steps_per_mm", axis.steps_per_mm, Range::positive(),
                                    cfg.drive == Drive::dc_servo ? Need::optional : Need::required);
    at_most(a, diag, has_steps, "steps_per_mm", axis.steps_per_mm, kMaxStepsPerMm, "1/mm");
    a.boolean("invert_direction", axis.invert_direction);
    if (a.has("encoder")) {
      MapReader enc = a.sub("encoder");
      EncoderConfig e;
      enc.number("resolution_um", e.resolution_um, Range::open_closed(0.0, 1000.0), Need::required);
      enc.number("index_period_mm", e.index_period_mm, Range::closed(0.0, 1000.0));
      enc.finish();
      axis.encoder = e;
    } else {
      a.sub("encoder");  // known key, for suggestions
    }
    const Need travel_need = is_e ? Need::optional : Need::required;
    const bool has_min = a.number("min_mm", axis.min_mm, Range::any(), travel_need);
    const bool has_max = a.number("max_mm", axis.max_mm, Range::any(), travel_need);
    if (has_min && has_max && !(axis.min_mm < axis.max_mm))
      diag.add(a.key_mark("max_mm"), a.path() + ": travel min_mm (" + format_number(axis.min_mm) +
                                         ") must be less than max_mm (" +
                                         format_number(axis.max_mm) + ")");
    if (is_e && has_min != has_max)
      diag.add(a.mark(), a.path() + ": give both min_mm and max_mm, or neither (unlimited)");
    const bool has_velocity =
        a.number("max_velocity_mm_s", axis.max_velocity_mm_s, Range::positive(), Need::required);
    at_most(a, diag, has_velocity, "max_velocity_mm_s", axis.max_velocity_mm_s, kMaxAxisVelocityMmS, "mm/s");
    const bool has_accel = a.number("max_accel_mm_s2", axis.max_accel_mm_s2, Range::positive(), Need::required);
    at_most(a, diag, has_accel, "max_accel_mm_s2", axis.max_accel_mm_s2, kMaxAxisAccelMmS2, "mm/s^2");
    if (has_steps && has_velocity && axis.steps_per_mm > 0.0 &&
        axis.steps_per_mm <= kMaxStepsPerMm && axis.max_velocity_mm_s <= kMaxAxisVelocityMmS &&
        axis.steps_per_mm * axis.max_velocity_mm_s > kMaxStepRateHz)
      diag.add(a.key_mark("steps_per_mm"),
               a.path() + ": steps_per_mm " + format_number(axis.steps_per_mm) + " x max_velocity_mm_s " +
                   format_number(axis.max_velocity_mm_s) + " = " +
                   format_number(axis.steps_per_mm * axis.max_velocity_mm_s) +
                   " steps/s, more than the step pipeline and the MCUs follow (" + format_number(kMaxStepRateHz) +
                   " steps/s); lower one of them");
    if (a.has("homing")) {
      if (is_e)
        diag.add(a.key_mark("homing"),
                 a.path() + ": the extruder has no endstop (homing is for the motion axes)");
      else
        read_homing(a, axis, diag);
    } else {
      a.sub("homing");  // known key, for suggestions
    }
    a.finish();
    cfg.axes.push_back(axis);
  }
  axes.finish();
  if (!axes.present() || !kinematics_known) return;  // already reported
  for (const std::string& need : required_axes(cfg.kinematics))
    if (cfg.axis(need) == nullptr && marks.axis.count(need) == 0)
      diag.add(axes.mark(), "kinematics " + kin + " needs axis '" + need + "', missing from axes");
}

void read_delta(MapReader& root, MachineConfig& cfg, Marks& marks, Diagnostics& diag) {
  const bool is_delta = cfg.kinematics == Kinematics::delta;
  if (!root.has("delta")) {
    root.sub("delta");  // known key
    if (is_delta)
      diag.add(marks.kinematics, "kinematics delta needs a 'delta' section (geometry)");
    return;
  }
  MapReader d = root.sub("delta");
  marks.delta = root.key_mark("delta");
  if (!is_delta) {
    diag.add(marks.delta, "section 'delta' is only valid with kinematics: delta");
    return;
  }
  DeltaGeometryConfig g;
  d.number("radius_mm", g.radius_mm, Range::positive(), Need::required);
  d.number("arm_length_mm", g.arm_length_mm, Range::positive(), Need::required);
  d.number("nozzle_offset_mm", g.nozzle_offset_mm, Range::any());
  d.number("angle_a_deg", g.angle_a_deg, Range::closed(-360.0, 360.0));
  d.number("angle_b_deg", g.angle_b_deg, Range::closed(-360.0, 360.0));
  d.number("angle_c_deg", g.angle_c_deg, Range::closed(-360.0, 360.0));
  d.number("print_radius_mm", g.print_radius_mm, Range::positive(), Need::required);
  const bool zmin = d.number("z_min_mm", g.z_min_mm, Range::any());
  const bool zmax = d.number("z_max_mm", g.z_max_mm, Range::any(), Need::required);
  if ((zmin || zmax) && !(g.z_min_mm < g.z_max_mm))
    diag.add(d.key_mark("z_max_mm"), "delta: z_min_mm (" + format_number(g.z_min_mm) +
                                         ") must be less than z_max_mm (" +
                                         format_number(g.z_max_mm) + ")");
  d.finish();
  cfg.delta = g;
}

}  // namespace feedloop::config::detail
