// Closed-loop simulation of the output-maneuvering controller on the DC-motor printer: the plant
// state (x_1, x_2) and the controller state (theta, omega_s) are integrated together with a fixed
// step classical RK4 (the controller is evaluated at every RK4 stage, i.e. a continuous-time
// controller), deterministically.
//
// Stepping, the paper's way (split_at_waypoints = false): every stage looks up the segment of its
// theta. With theta_n - theta_{n-1} = 1, one step advances theta by about m_s dt / ||Delta_n||, so
// a segment shorter than m_s dt is jumped over and never followed (Sect. V-A).
// Stepping that cannot skip (split_at_waypoints = true): a step keeps the segment it starts on for
// all its stages; a step whose theta would cross the segment's end is shortened to end at the
// waypoint (linear interpolation of the crossing, theta then set exactly to theta_n) and the rest
// of the step continues on the next segment. Every segment is entered in order, and the RK4
// stages never straddle the kink of dy_d/dtheta at a waypoint.
//
// Sampled servo (control_period_s > 0): a ManeuverServo (servo.hpp) is updated once per period
// with the plant state, its voltages are held (zero-order hold) while the plant is integrated in
// RK4 substeps of at most dt_s; errors and V are taken at the samples, as a servo would log them.
// simulate_sampled() runs the same servo against any SampledPlant (sampled_plant.hpp), e.g. one
// that is not the controller's model (offnominal_plant.hpp): the servo reads plant.measure(), and
// the errors are those of the true nozzle, plant.nozzle_m(), against y_d(theta).
//
// Along/cross-track errors follow Eq. 70 with phi the XY heading of the current segment (for a
// segment without XY extent, a layer change, cross-track is the XY norm of z_1).
#pragma once

#include <cstddef>
#include <vector>

#include "core/result.hpp"
#include "maneuver/controller.hpp"
#include "maneuver/sampled_plant.hpp"
#include "maneuver/servo.hpp"

namespace feedloop::maneuver {

struct SimOptions {
  double dt_s = 1.0e-4;             // fixed step
  bool split_at_waypoints = false;  // see above
  double control_period_s = 0.0;    // > 0: sampled servo at this period (see above)
  double max_time_s = 600.0;        // give up (finished = false) after this
  size_t record_every = 10;         // keep every k-th step in samples (0: none)
  PlantState initial{};             // initial plant state; default: at rest at p_0
  bool start_at_path = true;        // overwrite initial.x1_m with p_0
};

struct SimSample {
  double t_s;
  Vec3 pos_m;
  double theta;
  size_t segment;
  double along_m;      // s of Eq. 70
  double cross_m;      // e of Eq. 70
  double lyapunov;     // V of Eq. 51
  double speed_m_s;    // extruder speed ||x_2||
  double assigned_m_s; // ||dy_d/dtheta|| v_s: the assigned path speed
};

struct SimResult {
  std::vector<SimSample> samples;
  bool finished = false;        // theta reached theta_N
  double total_time_s = 0.0;    // time at which theta reached theta_N
  double max_cross_m = 0.0;     // ||e||_inf
  double iae_cross_m_s = 0.0;   // integral of |e| dt
  double max_along_m = 0.0;
  size_t steps = 0;             // integration steps taken (split steps count once per piece)
  size_t skipped_segments = 0;  // segments theta jumped over between two consecutive steps
  // segment_entry_s[n]: time the controller's segment became n (first time), -1 if never
  // (skipped); index 0 unused. Allocated before the loop.
  std::vector<double> segment_entry_s;
  double limited_fraction = 0.0;  // sampled runs: share of the periods in which a drive limit acted
};

Result<SimResult> simulate(const PiecewiseLinearPath& path, const SpeedAssignment& speed,
                           const ManeuverController& controller, const CartesianDcPlant& plant,
                           const SimOptions& options);

// The sampled servo at options.control_period_s (must be > 0) against `plant`, reset at p_0
// (options.initial and start_at_path are not used). The controller keeps its own model.
Result<SimResult> simulate_sampled(const PiecewiseLinearPath& path, const SpeedAssignment& speed,
                                   const ManeuverController& controller, SampledPlant& plant,
                                   const SimOptions& options);

}  // namespace feedloop::maneuver
