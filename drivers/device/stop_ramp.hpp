// A controlled stop of one motor: from the speed v0 at the start clock, decelerate at a constant
// rate to rest (no instant stop, which would make a moving carriage ring or a stepper slip):
//   p(tau) = p0 + v0 tau - sgn(v0) a tau^2 / 2,   tau in [0, |v0| / a],  then p0 + sgn(v0) v0^2 / (2 a).
// Owner: the axis loop. No heap, no exceptions.
#pragma once

#include <cstdint>

namespace feedloop::device {

class StopRamp {
 public:
  void start(int64_t clock, int64_t p0_nm, float v0_nm_s, float decel_nm_s2, float clock_hz);
  // Motor position (nm) the ramp wants at `clock`.
  int64_t position_at(int64_t clock) const;
  bool done_at(int64_t clock) const { return clock >= end_clock_; }
  int64_t end_clock() const { return end_clock_; }
  float v0_nm_s() const { return v0_; }

 private:
  int64_t t0_ = 0, end_clock_ = 0, p0_nm_ = 0;
  float v0_ = 0.0f, a_signed_ = 0.0f, inv_hz_ = 0.0f, t_end_s_ = 0.0f;
};

}  // namespace feedloop::device
