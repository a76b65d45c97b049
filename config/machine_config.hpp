// The printer description as plain structs: what one YAML config file holds (schema documented key
// by key in config/README.md). Every field has a sane default; units are in the names (mm, s, kg,
// N/m ...). Modules take the parts they need; nothing here knows YAML.
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace feedloop::config {

inline constexpr double kUnlimited = std::numeric_limits<double>::infinity();

enum class Kinematics { cartesian, corexy, delta };

// How the axes are driven: steppers fed with timed step batches by MCUs, or voltage-driven DC
// motors (the output-maneuvering paper's Cartesian printer, Sect. III-A), simulated in-process:
// no steps, no MCUs; it needs control.mode maneuver.
enum class Drive { stepper, dc_servo };

// ---- axes -------------------------------------------------------------------------------------

struct EncoderConfig {
  double resolution_um = 0.49;  // AS5311 linear encoder (thesis Sect. 3)
  double index_period_mm =
      0.0;  // its index marks' spacing (AS5311: 2 mm, one per pole pair); 0: none
  bool operator==(const EncoderConfig&) const = default;
};

// Homing through an endstop switch (axes.<name>.homing; docs/homing.md). Klipper's stepper keys
// (position_endstop, homing_speed, second_homing_speed, homing_retract_dist, homing_positive_dir)
// with their defaults; max_travel_mm is the fast approach's longest move (Klipper: 1.5 x the
// travel range). Read once at the edge into drivers::HomingParams (engine/mcu_bridge.cpp).
enum class EndstopSide { min, max };
struct HomingConfig {
  EndstopSide direction = EndstopSide::min;  // the switch's end of the travel
  double position_endstop_mm = 0.0;          // where the switch triggers (default: min_mm / max_mm)
  double homing_speed_mm_s = 5.0;            // Klipper's default
  double second_homing_speed_mm_s = 2.5;     // Klipper's default: homing_speed / 2
  double retract_dist_mm = 5.0;              // Klipper's homing_retract_dist; 0: no second touch
  double max_travel_mm = 0.0;                // default 1.5 x (max_mm - min_mm)
  // Encoder-index homing: after the switch, the encoder's next index mark away from it is the
  // reference (needs encoder.index_period_mm). index_position_mm: the mark's machine position
  // (unset: measured from the switch at the first G28 and logged, kept while the daemon runs).
  bool index = false;
  std::optional<double> index_position_mm;
  // Stall (sensorless) homing: no switch; the carriage is driven against the hard stop at
  // position_endstop_mm until the encoder falls stall_threshold_mm behind the steps (needs an
  // encoder; no second touch). The simulator puts a hard stop there.
  bool stall = false;
  double stall_threshold_mm = 0.5;
  bool operator==(const HomingConfig&) const = default;
};

// One motor axis: x, y, z, e (cartesian/corexy) or carriage A, B, C, e (delta). For corexy, x and
// y describe the two motors and the travel limits are Cartesian.
struct AxisConfig {
  std::string name;
  double steps_per_mm = 80.0;
  bool invert_direction = false;
  std::optional<EncoderConfig> encoder;  // none: open loop only on this axis
  double min_mm = -kUnlimited;           // travel limits; unlimited only for e
  double max_mm = kUnlimited;
  double max_velocity_mm_s = 300.0;
  double max_accel_mm_s2 = 3000.0;
  std::optional<HomingConfig> homing;  // none: G28 is the planner's move to the home position
  bool operator==(const AxisConfig&) const = default;
};

// ---- delta geometry (DESIGN.md canonical contract) -------------------------------------------

struct DeltaGeometryConfig {
  double radius_mm = 145.0;        // R, effective carriage radius
  double arm_length_mm = 300.0;    // L, forearm length
  double nozzle_offset_mm = 20.0;  // H_ez (delta paper Eq. 3-5)
  double angle_a_deg = 0.0;        // carriage A on +x
  double angle_b_deg = 120.0;
  double angle_c_deg = 240.0;
  double print_radius_mm = 100.0;  // reachable disc checked at load
  double z_min_mm = 0.0;
  double z_max_mm = 250.0;
  bool operator==(const DeltaGeometryConfig&) const = default;
};

// ---- planner ------------------------------------------------------------------------------------

enum class Cornering { junction_deviation, sharp_corner, speed_change };
enum class Profile { trapezoid, scurve };

// Output-maneuvering paper, Sect. III-D, Eq. 63-69: corners with angle alpha_n < alpha_a keep the
// speed, alpha_a..alpha_b slow down progressively (k_n of Eq. 66 from 0 to 1), > alpha_b slow down
// heavily; a1, a2 shape the sigmoid h of Eq. 68 (in path-parameter units, theta per segment = 1).
struct SharpCornerConfig {
  double alpha_a_deg = 5.0;   // Table II
  double alpha_b_deg = 20.0;  // Table II
  double a1 = 0.05;           // Table II
  double a2 = 0.005;          // Table II
  bool operator==(const SharpCornerConfig&) const = default;
};

struct PlannerConfig {
  double max_velocity_mm_s = 300.0;
  double max_accel_mm_s2 = 3000.0;  // thesis normal acceleration
  double junction_deviation_mm = 0.013;
  double square_corner_velocity_mm_s = 5.0;
  double min_cruise_ratio = 0.5;
  Cornering cornering = Cornering::junction_deviation;
  SharpCornerConfig sharp_corner;
  // cornering: speed_change (closed-loop-gantry-thesis Sect. 2.2): the largest velocity change at a
  // corner, |v u_out - v u_in|; 15 mm/s is Sailfish's default and the thesis's normal setting.
  double max_speed_change_mm_s = 15.0;
  Profile profile = Profile::trapezoid;
  double max_jerk_mm_s3 = 100000.0;  // scurve only
  int lookahead_moves = 128;
  double arc_tolerance_mm = 0.005;  // chordal deviation when splitting G2/G3
  // false: moves before G28 are refused ("Must home axis first"); true: the machine starts homed.
  bool allow_moves_before_homing = false;
  bool operator==(const PlannerConfig&) const = default;
};

// Klipper's [extruder] pressure advance (docs/pressure_advance.md): K in seconds (0: off; Marlin's
// M900 K, at most 10) and the smoothing window in seconds (Klipper's default 0.040, at most 0.200).
struct ExtruderConfig {
  double pressure_advance = 0.0;
  double pressure_advance_smooth_time = 0.040;
  // Klipper's [extruder] bounds, of the same names and defaults: no E move below this hotend
  // temperature (C; 0: none; M302 changes it), an E-only move of at most this length (mm), and at
  // most this cross-section of track (mm^2; 4 nozzle_diameter^2 unless given).
  double min_extrude_temp = 170.0;
  double max_extrude_only_distance = 50.0;
  double max_extrude_cross_section = 0.64;
  double nozzle_diameter = 0.4;
  double filament_diameter = 1.75;
  bool operator==(const ExtruderConfig&) const = default;
};

// ---- servo, control, feedforward ----------------------------------------------------------------

struct ServoConfig {
  double rate_hz = 1000.0;     // thesis: 1 kHz control update
  int realtime_priority = 80;  // SCHED_FIFO priority; 0: do not ask for real time
  int cpu = -1;                // pin the servo thread to this CPU; -1: no pinning
  bool lock_memory = true;     // mlockall when permitted
  bool operator==(const ServoConfig&) const = default;
};

enum class ControlMode { open_loop, pi, maneuver };
// Where mode pi's loop runs (issue 13): on each axis's MCU at its control rate, on the MCU's
// clock (device, the default: the thesis's IMC architecture), or on the host's servo thread
// (host: for real-time kernels, the LinuxCNC way).
enum class ControlLoop { device, host };

// Output maneuvering (output-maneuvering-cartesian Sect. III-C/D, docs/maneuver.md) for
// drive: dc_servo. Defaults: Table II, and the arc-length variant of the speed assignment.
enum class ManeuverSpeed { constant, every_transition, sharp_corner, sharp_corner_arc };
enum class ManeuverParameterization { unit, arc_length };

struct ManeuverControlConfig {
  double k_p_per_s = 500.0;    // K_p = -A_1 (Table II)
  double k_d_per_s = 1667.0;   // K_d = -A_2 (Table II); K_d / servo.rate_hz <= 1.5 (ZOH stability)
  double q1 = 1.0;             // Q_1 = q1 I
  double q2 = 1.0;             // Q_2 = q2 I
  double lambda_per_s = 30.0;  // filter of the gradient update (Eq. 52), rad/s
  double mu = 1.0e-3;          // gradient gain mu_1 in the controller's SI units (theta in m for
                               // arc_length: Table II's 1000 x (1 mm segment)^2)
  double path_speed_mm_s = 100.0;  // m_s (Fig. 7: 0.1 m/s)
  ManeuverSpeed speed_assignment = ManeuverSpeed::sharp_corner_arc;
  ManeuverParameterization parameterization = ManeuverParameterization::arc_length;
  double arc_a1_mm = 0.06;  // sharp_corner_arc: the Eq. 68 sigmoid in mm, and its reach
  double arc_a2_mm = 0.005;
  double arc_reach_mm = 2.0;
  bool operator==(const ManeuverControlConfig&) const = default;
};

// One axis's PI gains (control.axes.<axis>): the X and Y axes of a gantry have resonances a
// factor 4 apart (thesis Table 4: 80 / 21 Hz), so the gain one tolerates the other does not.
struct AxisGainsConfig {
  std::string axis;
  double kp = 0.5;
  double ki_per_s = 20.0;
  bool operator==(const AxisGainsConfig&) const = default;
};

struct ControlConfig {
  ControlMode mode = ControlMode::open_loop;  // pi needs encoders
  ControlLoop loop = ControlLoop::device;     // mode pi: where the PI runs
  double device_rate_hz = 1000.0;             // loop device: the MCU's control rate (thesis: 1 kHz)
  bool sub_step_trim = true;                  // loop device: the correction below a step as a
                                              // driver current phase (drivers with direct current
                                              // control; a no-op for others)
  double kp = 0.5;                            // thesis Sect. 5: P = 0.5
  double ki_per_s = 20.0;                     // thesis Sect. 5: I = 20
  double max_correction_mm_s = 50.0;          // clamp of the PI correction (per period: / rate_hz)
  double skipped_step_threshold_mm = 0.3;     // following error that counts as lost steps
  double max_following_error_mm = 2.0;        // beyond this: fault, stop motion
  double max_encoder_jump_mm =
      0.05;                        // an encoder sample beyond the travel possible since the
                                   // last good one (2 x max velocity x dt) plus this is implausible
  double command_lead_ms = 4.0;    // closed loop / feedforward: motor commands are computed
                                   // this far ahead of execution (the PI's loop delay)
  ManeuverControlConfig maneuver;  // mode maneuver (drive: dc_servo)
  std::vector<AxisGainsConfig> axes;  // per-axis kp / ki_per_s overrides

  // The gains of one axis (joint): its override, else the common kp / ki_per_s.
  AxisGainsConfig gains_for(const std::string& axis_name) const {
    for (const AxisGainsConfig& a : axes)
      if (a.axis == axis_name) return a;
    return AxisGainsConfig{axis_name, kp, ki_per_s};
  }
  bool operator==(const ControlConfig&) const = default;
};

enum class FeedforwardType { none, shaper, lpv };
enum class ShaperType { zv, mzv, ei };

// One axis's shaper. Fields an axis entry leaves out are taken from the common values at load.
struct AxisShaperConfig {
  std::string axis;
  ShaperType type = ShaperType::mzv;
  double freq_hz = 40.0;
  double damping = 0.1;
  bool operator==(const AxisShaperConfig&) const = default;
};

struct ShaperConfig {
  ShaperType type = ShaperType::mzv;
  double freq_hz = 40.0;
  double damping = 0.1;
  std::vector<AxisShaperConfig> axes;  // per-axis overrides (the X and Y resonances differ)

  // The shaper of one axis: its override, else the common values.
  AxisShaperConfig for_axis(const std::string& axis_name) const {
    for (const AxisShaperConfig& a : axes)
      if (a.axis == axis_name) return a;
    return AxisShaperConfig{axis_name, type, freq_hz, damping};
  }
  bool operator==(const ShaperConfig&) const = default;
};

struct LpvFeedforwardConfig {
  double preview_ms = 20.0;  // preview of the stable approximate inverse (DESIGN.md: RHP zero)
  bool freeze_at_centre =
      false;  // delta: the model of the centre everywhere (the fixed-model baseline)
  // A planned velocity jump (speed-change corners) is spread over the time it needs at this
  // acceleration before the inverse sees it (control/feedforward/velocity_jump_smoother.hpp);
  // 0: off. The window is at most jump_window_ms wide (it adds to the preview).
  double jump_accel_mm_s2 = 10000.0;
  double jump_window_ms = 31.0;
  bool operator==(const LpvFeedforwardConfig&) const = default;
};

struct FeedforwardConfig {
  FeedforwardType type = FeedforwardType::none;
  ShaperConfig shaper;
  LpvFeedforwardConfig lpv;
  bool operator==(const FeedforwardConfig&) const = default;
};

// ---- models -------------------------------------------------------------------------------------

// Nonlinear hybrid stepper + belt of the thesis, Appendix D Eq. 1-7 and Table 2.
struct StepperConfig {
  double holding_torque_nm = 0.285;  // T_max at rated current (17HD0013)
  double rated_current_a = 0.4;
  double drive_current_a = 0.2;            // drivers run below rated current; T_max scales with it
  int rotor_teeth = 50;                    // n_r
  double rotor_inertia_kg_m2 = 3.8e-6;     // J = 38 g cm^2
  double pulley_radius_mm = 5.40;          // r
  double belt_unit_stiffness_n =
      33000.0;  // k-hat of Eq. 6 (K_2 = k-hat / active length); 0: k2 uniform
  double pulley_distance_mm = 300.0;       // L of Eq. 6
  double belt_efficiency = 1.0;            // e of Eq. 7
  // One full step at the carriage, 2 pi r / (4 n_r) (0.1696 mm for Table 2's): a microstep
  // table's error and a detent repeat at it; the torque law (Eq. 2) every 4.
  double full_step_mm() const {
    return rotor_teeth > 0 ? 2.0 * 3.14159265358979323846 * pulley_radius_mm / (4.0 * rotor_teeth)
                           : 0.0;
  }
  bool operator==(const StepperConfig&) const = default;
};

// Linearised two-mass gantry axis of the thesis, Eq. 13 (Tables 3-4).
struct GantryModelConfig {
  std::string axis;
  double m1_kg = 0.130;             // rotor inertia as a mass, J / r^2 (Table 3)
  double m2_kg = 0.45;              // carriage / load mass (Table 2-3)
  double k1_n_per_m = 355e3;        // motor magnetic stiffness (Table 4)
  double k2_n_per_m = 110e3;        // belt stiffness (Table 4)
  double c1_ns_per_m = 2100.0;      // motor damping (Table 4)
  double c2_ns_per_m = 112.0;       // bearing damping (Table 4)
  double coulomb_friction_n = 0.0;  // sliding friction on the carriage (not in Eq. 13: what
                                    // `feedloop ident fit` reports as coulomb_friction force_n);
                                    // the LPV feedforward supplies it (docs/feedforward.md)
  double friction_bristle_mm = 0.02;  // Dahl presliding deflection at full friction (what
                                      // `feedloop ident fit` reports as presliding_um)
  double backlash_mm = 0.0;  // dead band between the pulley and the belt (not in Eq. 13: what
                             // `feedloop ident fit` reports as backlash width_um); the LPV
                             // feedforward crosses it ahead of each reversal of the belt force
  double belt_direction_ratio = 1.0;  // K2 pulling + / K2 pulling - beyond Eq. 6 (what `feedloop
                                      // ident fit` reports as direction_dependent_stiffness
                                      // ratio): the belt's stiffness is 2 r / (1 + r) of Eq. 6's
                                      // pulling + and 2 / (1 + r) pulling -; 1: none
  // The belt's compliance along the travel (what `feedloop calibrate` fits when the belt's
  // stiffness varies with the carriage's position): K2(x) = k2 / (1 + s (x - reference)), s in
  // 1/m, so k2_n_per_m is the stiffness at the reference; 0: a uniform belt (or Eq. 6's, below).
  double belt_compliance_slope_per_m = 0.0;
  double belt_stiffness_reference_mm = 0.0;
  // Pulley runout (what `feedloop ident fit` reports as periodic_position): the carriage reads
  // s sin(phi) + c (cos(phi) - 1) ahead of the motor, phi = 2 pi (x - reference) / period, with
  // the encoder zeroed at the reference (the calibration trace's start). period 0: none.
  double runout_period_mm = 0.0;
  double runout_sin_um = 0.0;
  double runout_cos_um = 0.0;
  double runout_reference_mm = 0.0;
  // The carriage's travel per mm of steps (what `feedloop ident fit` reports as scale_error
  // scale: a pulley or belt pitch off its nominal), counted from where the steps and the encoder
  // were last referenced to each other (a homing, the machine's start); the LPV feedforward
  // commands the steps that travel. 1: none.
  double travel_scale = 1.0;
  // A mode the two masses lack (what `feedloop ident fit` reports as extra_resonance): a mass on a
  // spring-damper on the carriage, its natural frequency and damping ratio there; the LPV
  // feedforward's model carries it. mass 0: none.
  double extra_resonance_hz = 0.0;
  double extra_resonance_damping = 0.0;
  double extra_resonance_mass_kg = 0.0;
  double encoder_delay_ms = 0.0;  // the encoder's reading shows the carriage this long ago (what
                                  // `feedloop ident fit` reports as time_delay delay_ms): the
                                  // loops and e_t compare it with the reference of that instant
  // The driver's field lag behind the step command, with c1 damping the load angle (the rotor
  // against the moving field, as a current-driven stepper does) instead of the rotor against the
  // frame (what `feedloop calibrate` fits when the data ask for it): the motor follows
  // u (1 + (c1 / k1) s) / (1 + field_lag s) through Eq. 13. 0: Eq. 13 as the thesis writes it
  // (the same model as field_lag = c1 / k1); the LPV feedforward inverts it.
  double field_lag_ms = 0.0;
  StepperConfig stepper;
  bool operator==(const GantryModelConfig&) const = default;
};

enum class ForceTransform { paper, virtual_work };

// Delta LPV receptance-coupling model: the physical parameters of the delta paper's Table I
// (DESIGN.md: its omega_n / zeta columns are inconsistent with them and are not used).
struct DeltaLpvConfig {
  double m_c_kg = 0.179;      // carriage mass
  double m_f_kg = 0.032;      // forearm pair mass (m = m_c + m_f / 2)
  double c_ns_per_m = 5.31;   // carriage damping to the motor (Eq. 37)
  double b_ns_per_m = 13.4;   // carriage damping to ground (Eq. 37)
  double k_n_per_m = 1.21e5;  // carriage stiffness
  double d0_per_s2 = 1.43e5;  // electrical part G_qd,e = (d1 s + d0)/(s^2 + d2 s + d0)
  double d1_per_s = -212.1;
  double d2_per_s = 36.2;
  double m1_kg = 0.542;        // end-effector: nozzle holder (Eq. 67)
  double m2_kg = 0.109;        // end-effector: extruder motor
  double b_x_ns_per_m = 20.4;  // b_j
  double b_y_ns_per_m = 40.5;
  double b_z_ns_per_m = 19.6;
  double k_x_n_per_m = 3.31e3;  // k_j
  double k_y_n_per_m = 7.04e3;
  double k_z_n_per_m = 1.29e5;
  double delta_x_mm = 10.21;  // centre-of-mass offset from the centroid (Eq. 20)
  double delta_y_mm = -16.52;
  double delta_z_mm = 19.31;
  double d_e_mm = 39.91;
  double gravity_m_s2 = 9.81;  // the effector's weight on the carriages (not in Eq. 29): the
                               // LPV feedforward supplies its position-dependent belt stretch //
                               // centroid to forearm reaction point (Eq. 20)
  ForceTransform force_transform = ForceTransform::paper;  // Eq. 25/69 vs tau = Jbar^T W X
  bool operator==(const DeltaLpvConfig&) const = default;
};

// The Cartesian DC-motor printer of output-maneuvering-cartesian Sect. III-A (Table I, Eq. 3-20):
// the plant of drive: dc_servo. Every key defaults to the paper's value.
struct CartesianDcConfig {
  double m_n_kg = 0.4;             // extruder system (nozzle)
  double m_x_kg = 0.2;             // x-axis motor (carried by z)
  double m_ps_kg = 0.8;            // print surface (y)
  double j_m_kg_m2 = 5.0e-6;       // motor + shaft + pulley inertia
  double b_nm_s = 1.1e-4;          // motor friction B, N m s/rad
  double r_a_ohm = 1.0e-3;         // armature resistance
  double k_m_nm_per_a = 1.0e-4;    // torque constant
  double pulley_radius_mm = 10.0;  // r
  bool operator==(const CartesianDcConfig&) const = default;
};

struct ModelConfig {
  std::vector<GantryModelConfig> gantry;  // per axis, in file order
  std::optional<DeltaLpvConfig> delta_lpv;
  CartesianDcConfig cartesian_dc;  // drive: dc_servo

  const GantryModelConfig* gantry_for(const std::string& axis_name) const {
    for (const GantryModelConfig& g : gantry)
      if (g.axis == axis_name) return &g;
    return nullptr;
  }
  bool operator==(const ModelConfig&) const = default;
};

// ---- step generation and MCUs -------------------------------------------------------------------

// What a device-loop MCU holds of the desired trajectory r(t): knots within this of r
// (engine/device_loop_link.cpp), this many per motor (drivers/device/target_queue.hpp; the
// engine asserts both), and r streamed this much further ahead than stepgen.queue_ahead_ms
// (the device's horizon margin and a knot's 10 ms in the compressor). The config check bounds
// queue_ahead_ms by them.
inline constexpr double kDeviceTargetToleranceMm = 0.5e-3;
inline constexpr int kDeviceTargetKnots = 512;
inline constexpr double kDeviceTargetMarginMs = 35.0;

struct StepgenConfig {
  double max_step_error_us = 5.0;        // compressed step times within this of the exact ones
  std::int64_t mcu_clock_hz = 72000000;  // default MCU clock; an MCU may override it
  double queue_ahead_ms = 250.0;         // how far ahead of its execution a step batch is sent
  bool operator==(const StepgenConfig&) const = default;
};

enum class TransportType { mock, serial, usb };

struct SerialConfig {
  std::string device;  // e.g. /dev/ttyACM0 or a /dev/serial/by-id/ link
  int baud = 250000;
  bool operator==(const SerialConfig&) const = default;
};

struct UsbConfig {
  int vid = 0;
  int pid = 0;
  std::string serial;  // empty: the first matching device
  bool operator==(const UsbConfig&) const = default;
};

struct McuConfig {
  std::string name;
  std::vector<std::string> axes;  // every axis is driven by exactly one MCU
  TransportType transport = TransportType::mock;
  SerialConfig serial;               // transport: serial
  UsbConfig usb;                     // transport: usb
  std::int64_t clock_hz = 72000000;  // defaults to stepgen.mcu_clock_hz
  bool operator==(const McuConfig&) const = default;
};

// ---- simulator ----------------------------------------------------------------------------------

// Unmodelled effects the plant simulator can add (vocabulary of DESIGN.md's identification report).
// Each is off unless present; `axes` empty means every motion axis.
struct CoulombFrictionConfig {
  double force_n = 2.0;
  std::vector<std::string> axes;
  bool operator==(const CoulombFrictionConfig&) const = default;
};
struct BacklashConfig {
  double width_um = 20.0;
  std::vector<std::string> axes;
  bool operator==(const BacklashConfig&) const = default;
};
struct PeriodicPositionConfig {
  double period_mm = 40.0;
  double amplitude_um = 10.0;
  double phase_deg = 0.0;
  std::vector<std::string> axes;
  bool operator==(const PeriodicPositionConfig&) const = default;
};
struct DirectionStiffnessConfig {
  double ratio = 1.3;
  std::vector<std::string> axes;
  bool operator==(const DirectionStiffnessConfig&) const = default;
};
struct ExtraResonanceConfig {
  double freq_hz = 90.0;
  double damping = 0.05;
  std::vector<std::string> axes;
  bool operator==(const ExtraResonanceConfig&) const = default;
};
struct TimeDelayConfig {
  double delay_ms = 2.0;
  std::vector<std::string> axes;
  bool operator==(const TimeDelayConfig&) const = default;
};
struct ScaleErrorConfig {
  double scale = 1.003;
  std::vector<std::string> axes;
  bool operator==(const ScaleErrorConfig&) const = default;
};

// Whether an effect (any of the structs above) acts on `axis_name`: an empty list means all axes.
template <class Effect>
bool applies_to(const Effect& effect, const std::string& axis_name) {
  if (effect.axes.empty()) return true;
  for (const std::string& a : effect.axes)
    if (a == axis_name) return true;
  return false;
}

struct SimEffectsConfig {
  std::optional<CoulombFrictionConfig> coulomb_friction;
  std::optional<BacklashConfig> backlash;
  std::optional<PeriodicPositionConfig> periodic_position;
  std::optional<DirectionStiffnessConfig> direction_dependent_stiffness;
  std::optional<ExtraResonanceConfig> extra_resonance;
  std::optional<TimeDelayConfig> time_delay;
  std::optional<ScaleErrorConfig> scale_error;
  bool operator==(const SimEffectsConfig&) const = default;
};

// DESIGN.md "External plant v1": the listed axes are driven by a plant in another process
// (sim/external_plant.hpp); the others stay on the built-in simulator.
struct ExternalPlantConfig {
  std::string command;            // run with /bin/sh -c
  std::vector<std::string> axes;  // config axis names, in the order of the plant's columns
  double period_us = 100.0;       // one exchange per period
  bool operator==(const ExternalPlantConfig&) const = default;
};

// The simulated endstop switches (sim/endstop.hpp), one on every axis with a homing section.
struct SimEndstopsConfig {
  double sigma_um = 2.0;           // trip point repeatability (1 sigma)
  double hysteresis_um = 50.0;     // released only this far back past the trip point
  double start_distance_mm = 2.0;  // power-on: the carriage this far from its switch (when the
                                   // machine must home: planner.allow_moves_before_homing false)
  bool operator==(const SimEndstopsConfig&) const = default;
};

struct SimulatorConfig {
  std::uint64_t seed = 1;
  double encoder_noise_um = 0.0;  // rms, added before quantisation to the encoder resolution
  double sample_delay_us = 0.0;   // encoder sample to report latency
  SimEffectsConfig effects;
  SimEndstopsConfig endstops;
  std::optional<ExternalPlantConfig> external_plant;
  bool operator==(const SimulatorConfig&) const = default;
};

// ---- daemon I/O ---------------------------------------------------------------------------------

// Paths may use ${RUNTIME_DIR} and ${STATE_DIR}; see expand_path() in config.hpp.
struct SocketsConfig {
  std::string unix_socket = "${RUNTIME_DIR}/feedloop.sock";  // G-code line protocol
  unsigned mode = 0660;                                      // permission bits of both sockets
  std::string api_socket = "${RUNTIME_DIR}/api.sock";        // JSON API
  std::string pty_link = "${RUNTIME_DIR}/ttyFeedloop";       // symlink to the Marlin-like pty
  bool operator==(const SocketsConfig&) const = default;
};

// The HTTP + WebSocket server for Mainsail/Fluidd (Moonraker's API; docs/web.md). Off unless
// enabled. Relative paths are taken from the daemon's working directory.
struct WebConfig {
  bool enabled = false;
  std::string address = "127.0.0.1";
  int port = 7125;
  std::vector<std::string> trusted_clients;  // CIDR ranges allowed without the API key
  std::string api_key;                       // X-Api-Key for everyone else (empty: none)
  std::string ui_dir;                        // the UI's static files, served at / (empty: none)
  std::string page_dir;   // feedloop's own page, served at /server/feedloop/page/
  std::string uplot_dir;  // uPlot's dist/, served at /server/feedloop/page/uplot/
  std::string files_dir = "${STATE_DIR}/files";      // roots gcodes/ and config/ (uploads)
  std::string database = "${STATE_DIR}/web.sqlite";  // server.database.* (SQLite)
  // feedloop's page shows the newest report.json of `feedloop ident fit --out DIR` found here
  // (in the folder itself or one level down: --out ${STATE_DIR}/ident/<name>).
  std::string calibration_dir = "${STATE_DIR}/ident";
  bool operator==(const WebConfig&) const = default;
};

struct RecorderConfig {
  bool enabled = true;
  std::string directory = "${STATE_DIR}/recordings";
  double max_file_size_mb = 256.0;  // rotate to a new file beyond this
  int keep_files = 20;              // oldest files beyond this are deleted
  bool operator==(const RecorderConfig&) const = default;
};

// Print jobs from files (daemon/print_job.hpp, docs/jobs.md): the folder and the pause/cancel
// moves.
struct JobsConfig {
  std::string directory = "${STATE_DIR}/gcodes";  // the job folder (created when missing)
  double max_file_size_mb = 512.0;                // uploads above this are refused
  double pause_retract_mm = 1.0;                  // filament pulled back on pause/cancel
  double retract_speed_mm_s = 30.0;
  double prime_extra_mm = 0.0;  // pushed on resume beyond the retract
  double lift_mm = 5.0;         // Z raise on pause/cancel (within Z's travel)
  double z_speed_mm_s = 10.0;
  // XY park point on pause/cancel. Unset: Marlin's NOZZLE_PARK_POINT default (X min + 10,
  // Y max - 10) on Cartesian and CoreXY machines; on a delta XY stay (only Z is raised).
  std::optional<double> park_x_mm, park_y_mm;
  double travel_speed_mm_s = 100.0;
  double settle_ms = 1000.0;  // dwell before a pause/resume position is taken (the device
                              // loop settles within a count in ~0.7 s)
  bool operator==(const JobsConfig&) const = default;
};

// Same order as spdlog::level::level_enum (the daemon casts between them).
enum class LogLevel { trace, debug, info, warn, error, critical, off };

struct LoggingConfig {
  LogLevel level = LogLevel::info;
  std::string file;  // empty: stderr (the journal under systemd) only
  bool operator==(const LoggingConfig&) const = default;
};

// ---- heaters and fans (docs/heaters.md)
// -----------------------------------------------------------

enum class HeaterKind { extruder, bed, chamber };

// A custom thermistor: the beta form or a three-point Steinhart-Hart fit (Klipper's thermistor
// section).
struct ThermistorConfig {
  enum class Form { beta, steinhart_hart } form = Form::beta;
  double t1_c = 25.0, r1_ohm = 100000.0;  // beta: the reference point
  double beta = 3950.0;
  double t2_c = 150.0, r2_ohm = 1641.9, t3_c = 250.0, r3_ohm = 226.15;
  bool operator==(const ThermistorConfig&) const = default;
};

struct HeaterProtectionConfig {  // Marlin's and Klipper's defaults; 0 disables a rule
  double watch_period_s = 20.0, watch_increase_c = 2.0;
  double runaway_period_s = 40.0, runaway_hysteresis_c = 4.0;
  double verify_max_error = 120.0, verify_gain_time_s = 20.0, verify_hysteresis_c = 5.0,
         verify_heating_gain_c = 2.0;
  double stuck_period_s = 10.0;
  bool operator==(const HeaterProtectionConfig&) const = default;
};

struct HeaterPlantConfig {  // the simulated printer's thermal plant (sim/thermal_plant.hpp)
  double power_w = 40.0, heat_capacity_j_k = 12.0, loss_w_k = 0.065, fan_loss_w_k = 0.05;
  double delay_s = 1.0, sensor_tau_s = 1.5, ambient_c = 22.0;
  bool operator==(const HeaterPlantConfig&) const = default;
};

struct HeaterConfig {
  std::string name;  // its key under heaters:
  HeaterKind kind = HeaterKind::extruder;
  std::string sensor = "EPCOS 100K B57560G104F";  // a built-in type, or "thermistor" (below)
  std::optional<ThermistorConfig> thermistor;
  double pullup_ohm = 4700.0;
  double min_temp_c = 0.0, max_temp_c = 275.0;
  double max_power = 1.0;
  double residency_s =
      10.0;  // M109/M190: time within 1 C before the wait ends (Marlin TEMP_RESIDENCY_TIME)
  double pid_kp = 22.2, pid_ki = 1.08, pid_kd = 114.0;  // Marlin/Klipper units (per 255 of power)
  HeaterProtectionConfig protection;
  HeaterPlantConfig plant;
  std::string mcu;  // the heater_mcus entry that drives it; "" = the simulated printer's board
  bool operator==(const HeaterConfig&) const = default;
};

enum class FanKind { part, heater };

struct FanConfig {
  std::string name;
  FanKind kind = FanKind::part;
  std::string heater;           // kind heater: the heater it cools
  double heater_temp_c = 50.0;  // kind heater: on above this
  double kick_start_s = 0.1;
  double off_below = 0.0;
  double max_power = 1.0;
  std::string mcu;  // the heater_mcus entry that drives it; "" = the simulated printer's board
  bool operator==(const FanConfig&) const = default;
};

// ---- the whole machine --------------------------------------------------------------------------

struct MachineConfig {
  std::string name = "feedloop printer";
  Kinematics kinematics = Kinematics::cartesian;
  Drive drive = Drive::stepper;
  std::vector<AxisConfig> axes;              // in file order
  std::optional<DeltaGeometryConfig> delta;  // present iff kinematics == delta
  PlannerConfig planner;
  ExtruderConfig extruder;
  ServoConfig servo;
  ControlConfig control;
  FeedforwardConfig feedforward;
  ModelConfig model;
  StepgenConfig stepgen;
  std::vector<McuConfig> mcus;
  SimulatorConfig simulator;
  std::vector<HeaterConfig> heaters;  // in file order
  std::vector<FanConfig> fans;
  // The boards that drive the heaters and fans (axes empty). None: the simulated printer's heater
  // board, which needs the motion MCUs simulated too (docs/heaters.md).
  std::vector<McuConfig> heater_mcus;
  SocketsConfig sockets;
  WebConfig web;
  RecorderConfig recorder;
  JobsConfig jobs;
  LoggingConfig logging;

  bool operator==(const MachineConfig&) const = default;

  const AxisConfig* axis(const std::string& axis_name) const {
    for (const AxisConfig& a : axes)
      if (a.name == axis_name) return &a;
    return nullptr;
  }
  bool uses_simulator() const {
    if (drive == Drive::dc_servo) return true;  // the DC-motor plant is simulated in-process
    for (const McuConfig& m : mcus)
      if (m.transport == TransportType::mock) return true;
    return false;
  }
};

}  // namespace feedloop::config
