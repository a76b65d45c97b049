// Config sections `planner`, `servo`, `control` and `feedforward`.
#include <cmath>  // ceil

#include "config/enum_names.hpp"
#include "config/sections.hpp"

namespace feedloop::config::detail {

void read_planner(MapReader& root, MachineConfig& cfg, Diagnostics& diag) {
  MapReader p = root.sub("planner");
  PlannerConfig& pl = cfg.planner;
  p.number("max_velocity_mm_s", pl.max_velocity_mm_s, Range::positive());
  p.number("max_accel_mm_s2", pl.max_accel_mm_s2, Range::positive());
  p.number("junction_deviation_mm", pl.junction_deviation_mm, Range::non_negative());
  p.number("square_corner_velocity_mm_s", pl.square_corner_velocity_mm_s, Range::non_negative());
  p.number("min_cruise_ratio", pl.min_cruise_ratio, Range::closed(0.0, 1.0));
  p.choice("cornering", pl.cornering, cornering_names());
  p.number("max_speed_change_mm_s", pl.max_speed_change_mm_s, Range::positive());  // thesis Sect. 2.2
  MapReader sc = p.sub("sharp_corner");
  SharpCornerConfig& s = pl.sharp_corner;
  // Eq. 64-66: alpha_a <= alpha_n <= alpha_b is the "sharp" band, angles in [0, 180] deg.
  const bool a = sc.number("alpha_a_deg", s.alpha_a_deg, Range::closed(0.0, 180.0));
  const bool b = sc.number("alpha_b_deg", s.alpha_b_deg, Range::closed(0.0, 180.0));
  sc.number("a1", s.a1, Range::non_negative());   // Eq. 68 shift
  sc.number("a2", s.a2, Range::positive());       // Eq. 68 scale
  if ((a || b) && !(s.alpha_a_deg < s.alpha_b_deg))
    diag.add(sc.key_mark(b ? "alpha_b_deg" : "alpha_a_deg"),
             "planner.sharp_corner: alpha_a_deg (" + format_number(s.alpha_a_deg) +
                 ") must be less than alpha_b_deg (" + format_number(s.alpha_b_deg) + ")");
  sc.finish();
  p.choice("profile", pl.profile, profile_names());
  p.number("max_jerk_mm_s3", pl.max_jerk_mm_s3, Range::positive());
  p.integer_as("lookahead_moves", pl.lookahead_moves, 2, 100000);
  p.number("arc_tolerance_mm", pl.arc_tolerance_mm, Range::open_closed(0.0, 10.0));
  p.boolean("allow_moves_before_homing", pl.allow_moves_before_homing);
  p.finish();
}

// extruder: Klipper's [extruder] pressure_advance (>= 0; Marlin's M900 bounds K to 10) and
// pressure_advance_smooth_time (Klipper: above 0, at most 0.200 s), both in seconds; its
// extrusion bounds min_extrude_temp, max_extrude_only_distance, max_extrude_cross_section (4
// nozzle_diameter^2 unless given), nozzle_diameter and filament_diameter.
void read_extruder(MapReader& root, MachineConfig& cfg, Diagnostics& /*diag*/) {
  MapReader e = root.sub("extruder");
  e.number("pressure_advance", cfg.extruder.pressure_advance, Range::closed(0.0, 10.0));
  e.number("pressure_advance_smooth_time", cfg.extruder.pressure_advance_smooth_time,
           Range::open_closed(0.0, 0.2));
  ExtruderConfig& x = cfg.extruder;
  e.number("min_extrude_temp", x.min_extrude_temp, Range::closed(0.0, 500.0));
  e.number("max_extrude_only_distance", x.max_extrude_only_distance, Range::closed(0.0, 1e4));
  e.number("nozzle_diameter", x.nozzle_diameter, Range::open_closed(0.0, 5.0));
  e.number("filament_diameter", x.filament_diameter, Range::open_closed(0.0, 5.0));
  x.max_extrude_cross_section = 4.0 * x.nozzle_diameter * x.nozzle_diameter;  // Klipper's default
  e.number("max_extrude_cross_section", x.max_extrude_cross_section, Range::closed(0.0, 100.0));
  e.finish();
}

namespace {

// control.maneuver: Table II gains, the path speed and the speed assignment (Sect. III-C/D).
void read_maneuver(MapReader& c, MachineConfig& cfg, Diagnostics& diag) {
  MapReader m = c.sub("maneuver");
  ManeuverControlConfig& mc = cfg.control.maneuver;
  const bool kd = m.number("k_d_per_s", mc.k_d_per_s, Range::positive());
  m.number("k_p_per_s", mc.k_p_per_s, Range::positive());
  m.number("q1", mc.q1, Range::positive());
  m.number("q2", mc.q2, Range::positive());
  m.number("lambda_per_s", mc.lambda_per_s, Range::positive());
  m.number("mu", mc.mu, Range::positive());
  m.number("path_speed_mm_s", mc.path_speed_mm_s, Range::open_closed(0.0, 10000.0));
  m.choice("speed_assignment", mc.speed_assignment, maneuver_speed_names());
  m.choice("parameterization", mc.parameterization, maneuver_parameterization_names());
  const bool a1 = m.number("arc_a1_mm", mc.arc_a1_mm, Range::non_negative());
  const bool a2 = m.number("arc_a2_mm", mc.arc_a2_mm, Range::positive());
  const bool reach = m.number("arc_reach_mm", mc.arc_reach_mm, Range::positive());
  if ((a1 || a2 || reach) && !(mc.arc_reach_mm > mc.arc_a1_mm + mc.arc_a2_mm))
    diag.add(m.key_mark(reach ? "arc_reach_mm" : (a1 ? "arc_a1_mm" : "arc_a2_mm")),
             "control.maneuver: arc_reach_mm (" + format_number(mc.arc_reach_mm) +
                 ") must exceed arc_a1_mm + arc_a2_mm (" + format_number(mc.arc_a1_mm + mc.arc_a2_mm) + ")");
  // The sampled (zero-order hold) controller diverges once K_d T passes about 1.6 (Table II's
  // K_d = 1667/s at 1 kHz: K_d T = 1.67 diverges, 0.9 ms: 1.5 holds; tests/maneuver/servo_test.cpp).
  const double kd_t = mc.k_d_per_s / cfg.servo.rate_hz;
  if (cfg.control.mode == ControlMode::maneuver && kd_t > 1.5)
    diag.add(kd ? m.key_mark("k_d_per_s") : c.key_mark("mode"),
             "control.maneuver.k_d_per_s (" + format_number(mc.k_d_per_s) + ") times the servo period (1/" +
                 format_number(cfg.servo.rate_hz) + " s) is " + format_number(kd_t) +
                 ": the sampled controller diverges above 1.5; raise servo.rate_hz to at least " +
                 format_number(std::ceil(mc.k_d_per_s / 1.5)) + " or lower k_d_per_s");
  m.finish();
}

// Each `<axis>: {...}` entry of the per-axis map `key` under `parent`, for an axis the config
// has (another name is an error at its key); read_one reads the entry's keys.
template <class ReadOne>
void read_per_axis(MapReader& parent, const char* key, const MachineConfig& cfg, Diagnostics& diag,
                   ReadOne&& read_one) {
  MapReader per_axis = parent.sub(key);
  for (const std::string& name : per_axis.keys()) {
    const YAML::Mark where = per_axis.key_mark(name);
    MapReader a(per_axis.get(name), per_axis.key_path(name), diag, where);
    if (cfg.axis(name) == nullptr) {
      diag.add(where, per_axis.path() + ": '" + name + "' is not an axis in axes");
      continue;
    }
    read_one(name, a);
    a.finish();
  }
  per_axis.finish();
}

}  // namespace

void read_servo_control(MapReader& root, MachineConfig& cfg, Diagnostics& diag) {
  MapReader s = root.sub("servo");
  s.number("rate_hz", cfg.servo.rate_hz, Range::closed(100.0, 20000.0));
  s.integer_as("realtime_priority", cfg.servo.realtime_priority, 0, 99);
  s.integer_as("cpu", cfg.servo.cpu, -1, 1023);
  s.boolean("lock_memory", cfg.servo.lock_memory);
  s.finish();

  MapReader c = root.sub("control");
  ControlConfig& cc = cfg.control;
  c.choice("mode", cc.mode, control_mode_names());
  c.choice("loop", cc.loop, control_loop_names());
  c.number("device_rate_hz", cc.device_rate_hz, Range::closed(100.0, 20000.0));
  c.boolean("sub_step_trim", cc.sub_step_trim);
  c.number("kp", cc.kp, Range::non_negative());
  c.number("ki_per_s", cc.ki_per_s, Range::non_negative());
  c.number("max_correction_mm_s", cc.max_correction_mm_s, Range::positive());
  const bool t = c.number("skipped_step_threshold_mm", cc.skipped_step_threshold_mm, Range::positive());
  const bool f = c.number("max_following_error_mm", cc.max_following_error_mm, Range::positive());
  c.number("max_encoder_jump_mm", cc.max_encoder_jump_mm, Range::positive());
  c.number("command_lead_ms", cc.command_lead_ms, Range::closed(1.0, 500.0));
  read_maneuver(c, cfg, diag);
  read_per_axis(c, "axes", cfg, diag, [&](const std::string& name, MapReader& a) {
    AxisGainsConfig own = cc.gains_for(name);  // inherit the common gains
    a.number("kp", own.kp, Range::non_negative());
    a.number("ki_per_s", own.ki_per_s, Range::non_negative());
    cc.axes.push_back(own);
  });
  if ((t || f) && !(cc.skipped_step_threshold_mm < cc.max_following_error_mm))
    diag.add(c.key_mark(f ? "max_following_error_mm" : "skipped_step_threshold_mm"),
             "control: skipped_step_threshold_mm (" + format_number(cc.skipped_step_threshold_mm) +
                 ") must be less than max_following_error_mm (" +
                 format_number(cc.max_following_error_mm) + ")");
  c.finish();

  MapReader ff = root.sub("feedforward");
  FeedforwardConfig& fc = cfg.feedforward;
  ff.choice("type", fc.type, feedforward_names());
  MapReader sh = ff.sub("shaper");
  sh.choice("type", fc.shaper.type, shaper_names());
  sh.number("freq_hz", fc.shaper.freq_hz, Range::closed(1.0, 500.0));
  sh.number("damping", fc.shaper.damping, Range::open(0.0, 1.0));
  read_per_axis(sh, "axes", cfg, diag, [&](const std::string& name, MapReader& a) {
    AxisShaperConfig own = fc.shaper.for_axis(name);  // inherit the common values
    a.choice("type", own.type, shaper_names());
    a.number("freq_hz", own.freq_hz, Range::closed(1.0, 500.0));
    a.number("damping", own.damping, Range::open(0.0, 1.0));
    fc.shaper.axes.push_back(own);
  });
  sh.finish();
  MapReader lpv = ff.sub("lpv");
  lpv.number("preview_ms", fc.lpv.preview_ms, Range::closed(0.0, 1000.0));
  lpv.boolean("freeze_at_centre", fc.lpv.freeze_at_centre);
  lpv.number("jump_accel_mm_s2", fc.lpv.jump_accel_mm_s2, Range::closed(0.0, 1e7));
  lpv.number("jump_window_ms", fc.lpv.jump_window_ms, Range::closed(0.0, 200.0));
  lpv.finish();
  ff.finish();
}

}  // namespace feedloop::config::detail
