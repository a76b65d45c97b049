// Motion of one joint (motor axis) over a time interval as a cubic polynomial. This is the contract
// between the planner (which emits joint motion) and step generation (which turns it into step
// times): for Cartesian/CoreXY joints every trapezoid phase is exactly quadratic (c3 = 0); for
// delta joints the planner emits cubic Hermite pieces per servo period.
//
//   pos_mm(t) = c0 + c1*tau + c2*tau^2 + c3*tau^3,  tau = t - t0_s,  0 <= tau <= duration_s
#pragma once

namespace feedloop {

struct JointSegment {
  double t0_s = 0.0;
  double duration_s = 0.0;
  double c0_mm = 0.0;      // position at t0
  double c1_mm_s = 0.0;    // velocity at t0
  double c2_mm_s2 = 0.0;   // half the acceleration at t0
  double c3_mm_s3 = 0.0;   // a sixth of the jerk

  double end_s() const { return t0_s + duration_s; }
  double position_mm(double t_s) const {
    const double tau = t_s - t0_s;
    return c0_mm + tau * (c1_mm_s + tau * (c2_mm_s2 + tau * c3_mm_s3));
  }
  double velocity_mm_s(double t_s) const {
    const double tau = t_s - t0_s;
    return c1_mm_s + tau * (2.0 * c2_mm_s2 + tau * 3.0 * c3_mm_s3);
  }
};

}  // namespace feedloop
