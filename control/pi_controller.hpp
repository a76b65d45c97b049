// PI correction of one joint on the encoder error (closed-loop-gantry-thesis Sect. 4.6, Fig. 6):
// the feedforward path F produces the motor command u_ff; this controller C adds the correction
//   u[k] = K_P e[k] + K_I sum_{m<=k} e[m] (t[m] - t[m-1])          (thesis Sect. 4.6, PI law)
// with e = desired carriage position - encoder position (mm). As in the thesis the change of the
// command per update is clamped "to keep the motor out of resonance": here the change of the
// correction, |u[k] - u[k-1]| <= max_correction_mm_s * T. Anti-windup by conditional integration
// (the integral does not grow further in the direction in which the output is clamped), and the
// integral term is bounded by integral_limit_mm. shift() moves the output at once, bypassing the
// clamp, for the recovery after lost steps (thesis Sect. 5.3-5.4; control/lost_step_detector.hpp).
// Owner: servo thread. configure() validates; everything else is RT-safe (no allocation, no locks).
#pragma once

#include <cstdint>

#include "core/result.hpp"

namespace feedloop::control {

struct PiParams {
  double kp = 0.5;                     // K_P (dimensionless: mm of correction per mm of error)
  double ki_per_s = 20.0;              // K_I (1/s)
  double period_s = 1e-3;              // T, the servo period
  double max_correction_mm_s = 50.0;   // clamp on the rate of change of u (per period: * T)
  double integral_limit_mm = 5.0;      // |K_I sum e dt| <= this (a few mm: > any steps/mm error)
  bool anti_windup = true;             // conditional integration (false only to show the windup)
};

class PiController {
 public:
  // Validates (gains >= 0, period > 0, limits > 0, all finite but the limits) and resets.
  Status configure(const PiParams& params);

  // RT-safe. One period: the error e[k] (mm) in, the correction u[k] (mm) to add to the
  // feedforward motor command out. A non-finite error holds the previous output.
  double update(double error_mm);
  // RT-safe. The same with the measured time since the previous update (the thesis's
  // t[m] - t[m-1]; e.g. 2 T after a missed deadline): integral and clamp scale with dt_s.
  // A dt_s that is not > 0 and finite is taken as the configured period.
  double update(double error_mm, double dt_s);

  // RT-safe. Bumpless gain change: the integral absorbs (K_P,old - K_P,new) e of the last error,
  // so the next update with the same error gives the same output. Negative or non-finite gains
  // are rejected (returns false, nothing changes).
  bool set_gains(double kp, double ki_per_s);

  // RT-safe. Output, integral and recovery offset to 0 (integrators reset: a safe state).
  void reset();

  // RT-safe. Moves the output by shift_mm at once (no clamp) and keeps it there: the shift goes
  // into a recovery offset beside the integral, so the integral limit does not bound it and the
  // next update continues from the shifted output.
  void shift(double shift_mm);

  double output_mm() const { return u_prev_mm_; }
  double integral_mm() const { return integral_mm_; }   // K_I sum e dt
  double offset_mm() const { return offset_mm_; }       // sum of shift()s since reset
  int saturated() const { return saturated_; }          // +1 / -1 when the last update was clamped, else 0
  std::int64_t saturated_count() const { return saturated_count_; }
  const PiParams& params() const { return p_; }

 private:
  PiParams p_{};
  double max_step_mm_ = 0.05;  // max_correction_mm_s * T
  double last_error_mm_ = 0.0;
  double integral_mm_ = 0.0;
  double offset_mm_ = 0.0;
  double u_prev_mm_ = 0.0;
  int saturated_ = 0;
  std::int64_t saturated_count_ = 0;
};

}  // namespace feedloop::control
