#include "engine/config_mapping.hpp"

#include <algorithm>  // std::min, std::max

namespace feedloop::engine {

std::array<std::string, kJoints> joint_names(const config::MachineConfig& cfg) {
  if (cfg.kinematics == config::Kinematics::delta) return {"A", "B", "C", "e"};
  return {"x", "y", "z", "e"};
}

planner::PlannerConfig planner_config(const config::MachineConfig& cfg) {
  planner::PlannerConfig p;
  switch (cfg.kinematics) {
    case config::Kinematics::cartesian: p.kinematics = planner::KinematicsKind::cartesian; break;
    case config::Kinematics::corexy: p.kinematics = planner::KinematicsKind::corexy; break;
    case config::Kinematics::delta: p.kinematics = planner::KinematicsKind::delta; break;
  }
  const auto names = joint_names(cfg);
  if (cfg.kinematics == config::Kinematics::delta && cfg.delta) {
    const config::DeltaGeometryConfig& g = *cfg.delta;
    p.delta.tower_angle_deg = {g.angle_a_deg, g.angle_b_deg, g.angle_c_deg};
    p.delta.radius_mm = g.radius_mm;
    p.delta.arm_length_mm = g.arm_length_mm;
    p.delta.nozzle_offset_mm = g.nozzle_offset_mm;
    p.delta.print_radius_mm = g.print_radius_mm;
    double lo = -1e12, hi = 1e12;
    for (int j = 0; j < 3; ++j) {
      if (const config::AxisConfig* a = cfg.axis(names[static_cast<size_t>(j)])) {
        lo = std::max(lo, a->min_mm);
        hi = std::min(hi, a->max_mm);
      }
    }
    p.delta.carriage_min_mm = lo;
    p.delta.carriage_max_mm = hi;
    p.min_position_mm = {-g.print_radius_mm, -g.print_radius_mm, g.z_min_mm, -1e12};
    p.max_position_mm = {g.print_radius_mm, g.print_radius_mm, g.z_max_mm, 1e12};
  } else {
    for (int j = 0; j < 3; ++j) {
      if (const config::AxisConfig* a = cfg.axis(names[static_cast<size_t>(j)])) {
        p.min_position_mm[static_cast<size_t>(j)] = a->min_mm;
        p.max_position_mm[static_cast<size_t>(j)] = a->max_mm;
      }
    }
  }
  // Per-axis limits (X Y Z E); for a delta the Cartesian axes take the planner's path limits.
  const char* cart[4] = {"x", "y", "z", "e"};
  for (int i = 0; i < 4; ++i) {
    const config::AxisConfig* a = cfg.axis(cart[i]);
    if (a == nullptr) continue;
    p.max_axis_velocity_mm_s[static_cast<size_t>(i)] = a->max_velocity_mm_s;
    p.max_axis_accel_mm_s2[static_cast<size_t>(i)] = a->max_accel_mm_s2;
  }
  p.max_velocity_mm_s = cfg.planner.max_velocity_mm_s;
  p.max_accel_mm_s2 = cfg.planner.max_accel_mm_s2;
  p.print_accel_mm_s2 = p.retract_accel_mm_s2 = p.travel_accel_mm_s2 = cfg.planner.max_accel_mm_s2;
  p.cornering = cfg.planner.cornering == config::Cornering::sharp_corner   ? planner::CorneringPolicy::sharp_corner
                : cfg.planner.cornering == config::Cornering::speed_change ? planner::CorneringPolicy::speed_change
                                                                           : planner::CorneringPolicy::junction_deviation;
  p.max_speed_change_mm_s = cfg.planner.max_speed_change_mm_s;
  p.junction_deviation_mm = cfg.planner.junction_deviation_mm;
  p.square_corner_velocity_mm_s = cfg.planner.square_corner_velocity_mm_s;
  p.sharp.alpha_a_deg = cfg.planner.sharp_corner.alpha_a_deg;
  p.sharp.alpha_b_deg = cfg.planner.sharp_corner.alpha_b_deg;
  p.sharp.a1 = cfg.planner.sharp_corner.a1;
  p.sharp.a2 = cfg.planner.sharp_corner.a2;
  p.min_cruise_ratio = cfg.planner.min_cruise_ratio;
  p.profile = cfg.planner.profile == config::Profile::scurve ? planner::ProfileShape::scurve
                                                             : planner::ProfileShape::trapezoid;
  p.max_jerk_mm_s3 = cfg.planner.max_jerk_mm_s3;
  p.lookahead_moves = static_cast<size_t>(std::max(2, cfg.planner.lookahead_moves));
  p.arc_tolerance_mm = cfg.planner.arc_tolerance_mm;
  p.allow_moves_before_homing = cfg.planner.allow_moves_before_homing;
  p.pressure_advance_s = cfg.extruder.pressure_advance;
  p.pressure_advance_smooth_time_s = cfg.extruder.pressure_advance_smooth_time;
  p.max_extrude_only_distance_mm = cfg.extruder.max_extrude_only_distance;
  p.max_extrude_cross_section_mm2 = cfg.extruder.max_extrude_cross_section;
  p.filament_diameter_mm = cfg.extruder.filament_diameter;
  p.nozzle_diameter_mm = cfg.extruder.nozzle_diameter;
  p.servo_period_s = 1.0 / cfg.servo.rate_hz;
  return p;
}

std::array<double, kJoints> steps_per_mm(const config::MachineConfig& cfg) {
  std::array<double, kJoints> out{};
  const auto names = joint_names(cfg);
  for (int j = 0; j < kJoints; ++j) {
    const config::AxisConfig* a = cfg.axis(names[static_cast<size_t>(j)]);
    out[static_cast<size_t>(j)] = a ? a->steps_per_mm : 0.0;
  }
  return out;
}

}  // namespace feedloop::engine
