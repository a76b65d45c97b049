// Planner configuration: machine limits, cornering policy, profile shape and kinematics geometry.
// Plain data with safe defaults (the corpus profile cart220.ini limits); validate() checks ranges.
#pragma once

#include <array>
#include <cstddef>

#include "core/result.hpp"

namespace feedloop::planner {

// Axis order used everywhere in the planner: X, Y, Z, E.
enum Axis : int { kX = 0, kY = 1, kZ = 2, kE = 3 };
inline constexpr int kAxes = 4;
using Vec4 = std::array<double, kAxes>;

enum class KinematicsKind { cartesian, corexy, delta };

// How the speed at the junction of two moves is chosen.
enum class CorneringPolicy {
  junction_deviation,  // Marlin/Klipper "approximated centripetal velocity"
  sharp_corner,        // output-maneuvering paper, Eq. 63-69 (slow down only at sharp corners)
  speed_change,        // closed-loop gantry thesis Sect. 2.2 (Marlin/Sailfish "max jerk"):
                       // |v u_next - v u_prev| <= max_speed_change_mm_s (vector norm, XYZ)
};

enum class ProfileShape { trapezoid, scurve };

// Canonical delta geometry (DESIGN.md contract): towers at 0/120/240 deg, R = 145, L = 300, H_ez = 20.
struct DeltaGeometry {
  std::array<double, 3> tower_angle_deg{0.0, 120.0, 240.0};
  double radius_mm = 145.0;        // effective carriage radius R
  double arm_length_mm = 300.0;    // forearm length L
  double nozzle_offset_mm = 20.0;  // H_ez, platform plane to nozzle tip
  double print_radius_mm = 135.0;  // reachable disk radius (bed of delta270.ini)
  double max_arm_angle_deg = 70.0; // arm angle from vertical must stay below this (no singularity)
  double carriage_min_mm = 0.0;    // carriage travel q_i (joint limits)
  double carriage_max_mm = 650.0;
  double check_step_mm = 2.0;      // spacing of the samples checked along a segment
};

// Parameters of the sharp-corner speed assignment (Eq. 66-68, Table II of the paper).
struct SharpCornerParams {
  double alpha_a_deg = 5.0;   // below: non-sharp, no slow-down
  double alpha_b_deg = 20.0;  // above: very sharp, heavy slow-down
  double a1 = 0.05;           // sigmoid h shift (Eq. 68)
  double a2 = 0.005;          // sigmoid h scale (Eq. 68)
};

struct PlannerConfig {
  KinematicsKind kinematics = KinematicsKind::cartesian;
  DeltaGeometry delta;

  // Travel limits of the Cartesian axes (cartesian/corexy; for delta z limits apply too).
  Vec4 min_position_mm{0.0, 0.0, 0.0, -1e12};
  Vec4 max_position_mm{220.0, 220.0, 250.0, 1e12};
  Vec4 home_position_mm{0.0, 0.0, 0.0, 0.0};

  // Per-axis limits (M203 / M201 in the G-code), X Y Z E.
  Vec4 max_axis_velocity_mm_s{300.0, 300.0, 12.0, 120.0};
  Vec4 max_axis_accel_mm_s2{3000.0, 3000.0, 100.0, 5000.0};
  double max_velocity_mm_s = 300.0;  // along the path
  double max_accel_mm_s2 = 3000.0;   // upper bound of every M204 value
  // Default M204 values: printing (P), retract (R, E-only moves), travel (T).
  double print_accel_mm_s2 = 3000.0;
  double retract_accel_mm_s2 = 3000.0;
  double travel_accel_mm_s2 = 3000.0;

  CorneringPolicy cornering = CorneringPolicy::junction_deviation;
  // Junction deviation: if > 0 it is used as is (Marlin, M205 J); otherwise it is derived from
  // Klipper's square_corner_velocity: jd = scv^2 (sqrt 2 - 1) / max_accel.
  double junction_deviation_mm = 0.0;
  double square_corner_velocity_mm_s = 5.0;
  SharpCornerParams sharp;
  // Speed change: the largest velocity change allowed at a junction (thesis Sect. 2.2; Sailfish's
  // default and the thesis's normal setting is 15 mm/s, Sect. 5.4).
  double max_speed_change_mm_s = 15.0;
  // Klipper's minimum_cruise_ratio: accel_to_decel = accel * (1 - ratio).
  double min_cruise_ratio = 0.5;

  ProfileShape profile = ProfileShape::trapezoid;
  double max_jerk_mm_s3 = 1.0e5;   // S-curve jerk bound

  size_t lookahead_moves = 256;    // bounded window
  double arc_tolerance_mm = 0.01;  // chordal tolerance of G2/G3 segments
  double servo_period_s = 0.001;   // delta joint output: one cubic Hermite piece per period
  double homing_velocity_mm_s = 50.0;
  // Moves of an axis before it is homed (G28) are refused (Klipper: "Must home axis first";
  // Marlin: NO_MOTION_BEFORE_HOMING). true restores the old behaviour: the machine starts homed
  // at home_position_mm (config planner.allow_moves_before_homing).
  bool allow_moves_before_homing = false;

  // Firmware retraction defaults (Marlin), changed by M207/M208.
  double retract_length_mm = 3.0;
  double retract_velocity_mm_s = 45.0;
  double retract_zlift_mm = 0.0;
  double unretract_extra_mm = 0.0;
  double unretract_velocity_mm_s = 8.0;

  // Pressure advance (planner/pressure_advance.hpp): K in seconds (Marlin's M900 K, Klipper's
  // pressure_advance) and the smoothing window (Klipper's pressure_advance_smooth_time).
  double pressure_advance_s = 0.0;
  double pressure_advance_smooth_time_s = 0.040;

  // Extrusion bounds (Klipper's [extruder] options of the same names): an E-only move longer than
  // max_extrude_only_distance_mm is refused, and so is a move that would push more filament per
  // mm of travel than a track of max_extrude_cross_section_mm2 takes (unless the amount is tiny:
  // at most nozzle_diameter_mm of such a track). 0 turns either off.
  double max_extrude_only_distance_mm = 50.0;
  double max_extrude_cross_section_mm2 = 0.64;  // Klipper's default: 4 nozzle_diameter^2
  double filament_diameter_mm = 1.75;
  double nozzle_diameter_mm = 0.4;

  double junction_deviation() const;
  Status validate() const;
};

}  // namespace feedloop::planner
