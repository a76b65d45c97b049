// Kinematics factory and the PlannerConfig helpers.
#include "planner/kinematics.hpp"

#include <cmath>  // sqrt

#include "planner/delta_kinematics.hpp"
#include "planner/linear_kinematics.hpp"

namespace feedloop::planner {

std::unique_ptr<Kinematics> make_kinematics(const PlannerConfig& c) {
  if (c.kinematics == KinematicsKind::delta) {
    return std::make_unique<DeltaKinematics>(c.delta, c.min_position_mm[kZ], c.max_position_mm[kZ]);
  }
  return std::make_unique<LinearKinematics>(c.kinematics, c.min_position_mm, c.max_position_mm);
}

double PlannerConfig::junction_deviation() const {
  if (junction_deviation_mm > 0.0) return junction_deviation_mm;
  // Klipper toolhead.py: scv^2 * (sqrt(2) - 1) / max_accel
  return square_corner_velocity_mm_s * square_corner_velocity_mm_s * (std::sqrt(2.0) - 1.0) / max_accel_mm_s2;
}

Status PlannerConfig::validate() const {
  auto bad = [](const char* what) { return Status(Error{std::string("planner config: ") + what, {}}); };
  for (int i = 0; i < kAxes; ++i) {
    if (!(max_axis_velocity_mm_s[i] > 0.0)) return bad("max axis velocity must be > 0");
    if (!(max_axis_accel_mm_s2[i] > 0.0)) return bad("max axis accel must be > 0");
    if (!(min_position_mm[i] <= max_position_mm[i])) return bad("min position must be <= max position");
  }
  if (!(max_velocity_mm_s > 0.0) || !(max_accel_mm_s2 > 0.0)) return bad("max velocity and accel must be > 0");
  if (!(print_accel_mm_s2 > 0.0) || !(retract_accel_mm_s2 > 0.0) || !(travel_accel_mm_s2 > 0.0))
    return bad("M204 defaults must be > 0");
  if (!(min_cruise_ratio >= 0.0 && min_cruise_ratio < 1.0)) return bad("min_cruise_ratio must be in [0, 1)");
  if (!(square_corner_velocity_mm_s >= 0.0) || !(junction_deviation_mm >= 0.0)) return bad("cornering values must be >= 0");
  if (!(sharp.alpha_a_deg >= 0.0 && sharp.alpha_a_deg < sharp.alpha_b_deg && sharp.alpha_b_deg <= 180.0))
    return bad("sharp corner angles need 0 <= alpha_a < alpha_b <= 180");
  if (!(sharp.a2 > 0.0)) return bad("sharp corner a2 must be > 0");
  if (!(max_speed_change_mm_s > 0.0)) return bad("max_speed_change_mm_s must be > 0");
  if (!(max_jerk_mm_s3 > 0.0)) return bad("S-curve jerk must be > 0");
  if (lookahead_moves < 2 || lookahead_moves > 100000) return bad("lookahead_moves must be in [2, 100000]");
  if (!(arc_tolerance_mm > 0.0)) return bad("arc tolerance must be > 0");
  if (!(servo_period_s > 0.0 && servo_period_s <= 0.1)) return bad("servo period must be in (0, 0.1] s");
  if (!(pressure_advance_s >= 0.0 && pressure_advance_s <= 10.0))
    return bad("pressure advance must be in [0, 10] s");
  if (!(pressure_advance_smooth_time_s > 0.0 && pressure_advance_smooth_time_s <= 0.2))
    return bad("pressure advance smooth time must be in (0, 0.2] s");
  if (!(max_extrude_only_distance_mm >= 0.0) || !(max_extrude_cross_section_mm2 >= 0.0))
    return bad("extrusion bounds must be >= 0");
  if (!(filament_diameter_mm > 0.0) || !(nozzle_diameter_mm > 0.0))
    return bad("filament and nozzle diameters must be > 0");
  if (kinematics == KinematicsKind::delta) {
    const DeltaGeometry& d = delta;
    if (!(d.radius_mm > 0.0 && d.arm_length_mm > d.radius_mm && d.print_radius_mm > 0.0))
      return bad("delta geometry needs R > 0, L > R, print radius > 0");
    if (!(d.max_arm_angle_deg > 0.0 && d.max_arm_angle_deg < 90.0)) return bad("delta max arm angle must be in (0, 90) deg");
    if (!(d.check_step_mm > 0.0)) return bad("delta check step must be > 0");
  }
  return {};
}

}  // namespace feedloop::planner
