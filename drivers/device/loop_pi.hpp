// The PI law of the device loop (closed-loop-gantry thesis Sect. 4.6):
//   u[k] = K_P e[k] + K_I sum_{m<=k} e[m] (t[m] - t[m-1])
// with t the MCU time of each encoder sample, so a late or skipped tick integrates the time that
// really passed (not "one period"). Output clamp |u| <= u_max with anti-windup by conditional
// integration: while the output is clamped the integral does not grow in the clamped direction.
// shift() moves the output at once and keeps it there (the recovery after a skipped step,
// slip_detector.hpp). set_gains() is bumpless: the integral absorbs (K_P,old - K_P,new) e of the
// last error, so the output does not jump when the gains change.
// float arithmetic: a Cortex-M4 has a single-precision FPU; errors are < 1e7 nm, resolved to < 1 nm.
// Owner: the axis loop. No heap, no exceptions.
#pragma once

namespace feedloop::device {

class LoopPi {
 public:
  void configure(float kp, float ki_per_s, float max_output_nm);
  void reset();
  // One tick: error e (nm), dt_s = t[k] - t[k-1] (s, MCU time). Returns u (nm). integrate false:
  // the integral is held this tick (an error inside the sensor's resolution).
  // p_band_nm: the proportional term acts on the error beyond +-p_band_nm only (0: on all of it).
  float update(float error_nm, float dt_s, bool integrate = true, float p_band_nm = 0.0f);
  // Bumpless gain and clamp change (the output for the last error stays the same).
  void set_gains(float kp, float ki_per_s, float max_output_nm);
  void shift(float shift_nm);
  // Restores the integral (the recovery after a slip drops what it gained from the slip's error).
  void set_integral(float integral_nm) { integral_nm_ = integral_nm; }
  // Sets the integral so that the output for the last error is u_nm (a motion's start: the output
  // the steps already made, without the fraction of a step the integral held at rest).
  void set_output(float u_nm) {
    integral_nm_ = u_nm - offset_nm_ - kp_ * last_p_error_nm_;
    u_nm_ = u_nm;
  }

  float output_nm() const { return u_nm_; }
  float integral_nm() const { return integral_nm_; }
  float offset_nm() const { return offset_nm_; }
  float kp() const { return kp_; }
  float ki_per_s() const { return ki_per_s_; }
  int saturated() const { return saturated_; }

 private:
  float kp_ = 0.0f, ki_per_s_ = 0.0f, max_nm_ = 0.0f;
  float integral_nm_ = 0.0f;  // K_I sum e dt
  float offset_nm_ = 0.0f;    // sum of shift()s
  float last_error_nm_ = 0.0f;
  float last_p_error_nm_ = 0.0f;  // the part of the last error the proportional term acted on
  float u_nm_ = 0.0f;
  int saturated_ = 0;
};

}  // namespace feedloop::device
