// Whole-machine checks run after every section was read: each axis driven by an MCU, the delta
// print volume reachable by the arms and the carriage travel, controller needs met.
#include <cmath>    // sqrt, cos, sin, hypot
#include <numbers>  // pi

#include "config/enum_names.hpp"
#include "config/sections.hpp"

namespace feedloop::config::detail {
namespace {

// Delta paper Eq. 3-5: (x - i_x)^2 + (y - i_y)^2 + (z + H_ez - q_i)^2 = L^2, so the carriage height
// for a nozzle at (x, y, z) is q_i = z + H_ez + sqrt(L^2 - d_i^2), d_i the horizontal distance from
// the nozzle to carriage i's tower. Checks the disc of print_radius_mm at z_min and z_max.
void check_delta_reach(const MachineConfig& cfg, const Marks& marks, Diagnostics& diag) {
  const DeltaGeometryConfig& g = *cfg.delta;
  const double deg = std::numbers::pi / 180.0;
  const double angles[3] = {g.angle_a_deg * deg, g.angle_b_deg * deg, g.angle_c_deg * deg};
  const char* names[3] = {"A", "B", "C"};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < i; ++j) {
      const double diff = std::remainder(angles[i] - angles[j], 2 * std::numbers::pi);
      if (std::fabs(diff) < 10.0 * deg)
        diag.add(marks.delta, std::string("delta: carriages ") + names[j] + " and " + names[i] +
                                  " are less than 10 deg apart");
    }
  }
  constexpr int kSamples = 360;
  for (int i = 0; i < 3; ++i) {
    const double tx = g.radius_mm * std::cos(angles[i]);
    const double ty = g.radius_mm * std::sin(angles[i]);
    double d_max = 0.0, d_min = 1e300;
    for (int k = 0; k <= kSamples; ++k) {
      // k == kSamples: the centre of the bed.
      const double phi = 2.0 * std::numbers::pi * k / kSamples;
      const double r = k == kSamples ? 0.0 : g.print_radius_mm;
      const double d = std::hypot(r * std::cos(phi) - tx, r * std::sin(phi) - ty);
      d_max = std::max(d_max, d);
      d_min = std::min(d_min, d);
    }
    if (!(d_max < g.arm_length_mm)) {
      diag.add(marks.delta, "delta geometry unreachable: the edge of the print disc "
                            "(print_radius_mm " + format_number(g.print_radius_mm) + ") is " +
                                format_number(d_max) + " mm from carriage " + names[i] +
                                "'s tower, not less than arm_length_mm " +
                                format_number(g.arm_length_mm));
      continue;
    }
    const double q_min = g.z_min_mm + g.nozzle_offset_mm +
                         std::sqrt(g.arm_length_mm * g.arm_length_mm - d_max * d_max);
    const double q_max = g.z_max_mm + g.nozzle_offset_mm +
                         std::sqrt(g.arm_length_mm * g.arm_length_mm - d_min * d_min);
    const AxisConfig* axis = cfg.axis(names[i]);
    if (axis == nullptr) continue;
    if (q_min < axis->min_mm || q_max > axis->max_mm) {
      const auto it = marks.axis.find(names[i]);
      diag.add(it != marks.axis.end() ? it->second : marks.delta,
               std::string("carriage ") + names[i] + " must travel " + format_number(std::floor(q_min)) +
                   " .. " + format_number(std::ceil(q_max)) +
                   " mm to cover the print volume (delta print_radius_mm, z_min_mm..z_max_mm), "
                   "but its travel is " + format_number(axis->min_mm) + " .. " +
                   format_number(axis->max_mm) + " mm");
    }
  }
}

}  // namespace

void check_machine(const MachineConfig& cfg, const Marks& marks, Diagnostics& diag) {
  // Every axis is driven by exactly one MCU (a second MCU is reported where it is listed).
  if (!cfg.mcus.empty()) {
    for (const AxisConfig& a : cfg.axes) {
      bool driven = false;
      for (const McuConfig& m : cfg.mcus)
        for (const std::string& n : m.axes) driven = driven || n == a.name;
      if (!driven) {
        const auto it = marks.axis.find(a.name);
        diag.add(it != marks.axis.end() ? it->second : marks.axes,
                 "axis '" + a.name + "' is not driven by any mcu (add it to one mcus[].axes list)");
      }
    }
  }
  if (cfg.kinematics == Kinematics::delta && cfg.delta) check_delta_reach(cfg, marks, diag);

  // CoreXY homing moves both motors step for step (x = (A + B) / 2, y = (A - B) / 2: one step of
  // the carriage is one step of each), so both belts need the same steps/mm; and the carriage
  // homes X and Y through both motors, so a homing section needs the other axis's too.
  if (cfg.kinematics == Kinematics::corexy) {
    const AxisConfig* x = cfg.axis("x");
    const AxisConfig* y = cfg.axis("y");
    if (x && y && (x->homing || y->homing)) {
      const AxisConfig& h = x->homing ? *x : *y;
      const auto it = marks.axis.find(h.name);
      const YAML::Mark where = it != marks.axis.end() ? it->second : marks.axes;
      if (x->steps_per_mm != y->steps_per_mm)
        diag.add(where, "axes." + h.name + ".homing: corexy homing moves motors A and B step for step: "
                        "x and y need the same steps_per_mm (" + format_number(x->steps_per_mm) +
                            " and " + format_number(y->steps_per_mm) + ")");
      if (!x->homing || !y->homing)
        diag.add(where, "axes." + h.name + ".homing: a corexy carriage homes through both motors: give "
                        "x and y a homing section each (or neither)");
    }
  }

  // Step batches must be sent at least two servo periods ahead of their execution, or every
  // period would arrive late at the MCU.
  const double period_ms = 1000.0 / cfg.servo.rate_hz;
  if (cfg.stepgen.queue_ahead_ms < 2.0 * period_ms)
    diag.add(marks.stepgen, "stepgen.queue_ahead_ms (" + format_number(cfg.stepgen.queue_ahead_ms) +
                                ") must be at least two servo periods (" +
                                format_number(2.0 * period_ms) + " ms at servo.rate_hz " +
                                format_number(cfg.servo.rate_hz) + ")");

  // Device loop: each MCU holds kDeviceTargetKnots knots of r(t) per motor. Knots within a
  // tolerance e of r lie at least sqrt(8 e / a) apart where r accelerates at a (a chord's sag is
  // a dt^2 / 8), so a lead that covers more knots than that at the planner's acceleration would
  // overflow the queue on a tight curve: a controlled stop mid-print ("target queue full").
  // Measured on the circles plate at 1500 mm/s^2 (docs/decisions.md): 735 ms of r(t) fit, 1035 ms
  // did not; this bound says 836 ms. A CoreXY motor's r is x + y (up to sqrt 2 a); a delta's
  // carriage accelerates up to about twice the nozzle near the edge of its disc.
  if (cfg.control.mode == ControlMode::pi && cfg.control.loop == ControlLoop::device) {
    const double factor = cfg.kinematics == Kinematics::corexy  ? std::numbers::sqrt2
                          : cfg.kinematics == Kinematics::delta ? 2.0
                                                                : 1.0;
    const double accel_mm_s2 = factor * cfg.planner.max_accel_mm_s2;
    const double knots_per_s = std::sqrt(accel_mm_s2 / (8.0 * kDeviceTargetToleranceMm));
    const double usable_knots = kDeviceTargetKnots - 16.0;  // a message of knots in flight
    const double max_lead_ms = usable_knots / knots_per_s * 1e3 - kDeviceTargetMarginMs;
    if (accel_mm_s2 > 0.0 && cfg.stepgen.queue_ahead_ms > max_lead_ms)
      diag.add(
          marks.stepgen,
          "stepgen.queue_ahead_ms (" + format_number(cfg.stepgen.queue_ahead_ms) +
              ") is more of r(t) than the device loop's MCUs hold: at planner.max_accel_mm_s2 " +
              format_number(cfg.planner.max_accel_mm_s2) + " its knots come up to " +
              format_number(std::round(knots_per_s)) + " a second and an MCU holds " +
              std::to_string(kDeviceTargetKnots) + " per motor: at most " +
              format_number(std::floor(max_lead_ms)) + " ms");
  }

  if (cfg.control.mode == ControlMode::pi) {
    bool any_encoder = false;
    for (const AxisConfig& a : cfg.axes) any_encoder = any_encoder || a.encoder.has_value();
    if (!any_encoder && !cfg.axes.empty())
      diag.add(marks.control, "control.mode is pi but no axis has an encoder; add axes.<name>.encoder "
                           "or use mode: open_loop");
  }
  // drive: dc_servo is the output-maneuvering paper's Cartesian printer, and maneuver control
  // needs its voltage-driven axes.
  if (cfg.drive == Drive::dc_servo) {
    if (cfg.kinematics != Kinematics::cartesian)
      diag.add(marks.drive, "drive: dc_servo is a Cartesian printer (output-maneuvering model); kinematics is " +
                                enum_name(kinematics_names(), cfg.kinematics));
    if (cfg.control.mode != ControlMode::maneuver)
      diag.add(marks.control, "drive: dc_servo needs control.mode: maneuver (voltage-driven axes are not "
                              "stepped); mode is " + enum_name(control_mode_names(), cfg.control.mode));
  } else if (cfg.control.mode == ControlMode::maneuver) {
    diag.add(marks.control, "control.mode maneuver drives voltage-driven axes: it needs drive: dc_servo");
  }
  if (cfg.feedforward.type == FeedforwardType::lpv && cfg.model.gantry.empty() &&
      !cfg.model.delta_lpv)
    diag.add(marks.feedforward, "feedforward.type lpv needs a model: model.gantry (cartesian/corexy) or "
                         "model.delta_lpv (delta)");
}

}  // namespace feedloop::config::detail
