// One corner at a time (bench_maneuver table E, docs/maneuver.md "The unit"): a leg, a turn made of
// one or more equal turns joined by chords, a leg, followed by the controller on its own model
// (Table I/II, continuous). With the exact model the closed loop is linear in z (Eq. 55), so a
// corner's error is its velocity jump times one response, and its size and duration bound what
// any layer can show.
#pragma once

#include <vector>

#include "core/result.hpp"
#include "maneuver/path.hpp"
#include "maneuver/speed_assignment.hpp"

namespace feedloop::maneuver {

// A leg_m leg along x, a turn of turn_deg in `turns` equal turns joined by chords of chord_m (one
// turn: a sharp corner; more: the corner as a slicer rounds it), a leg_m leg.
std::vector<Vec3> corner_path(double turn_deg, int turns, double chord_m, double leg_m = 0.03);

struct CornerResponse {
  double max_cross_m = 0.0;    // largest |e| of Eq. 70
  double max_z1_m = 0.0;       // largest |z_1| (along and cross; the start from rest included)
  double iae_cross_m_s = 0.0;  // integral of |e|
  double settle_s = 0.0;       // from the first corner until |e| stays below 1 % of its peak
};

// The path with the unit parameterisation (Eq. 24-25), RK4 at 1e-4 s. Errors: a path or speed
// assignment that cannot be built, or a run that does not finish.
Result<CornerResponse> corner_response(const std::vector<Vec3>& waypoints_m, SpeedProfile profile,
                                       const SpeedParams& speed);

}  // namespace feedloop::maneuver
