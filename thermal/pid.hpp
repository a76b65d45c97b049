// The heater's PID, as Klipper's ControlPID (klippy/extras/heaters.py) runs it on the host:
// gains in Marlin/Klipper units (output 0..255 per degree; divided by 255 here, so the power is a
// fraction 0..1), the derivative taken on the measured temperature (no kick when the target
// changes) and smoothed over smooth_time_s, and anti-windup by conditional integration: the
// integral keeps its new value only when the output is not clamped, and is bounded so that
// Ki * integral alone never exceeds max_power. No allocation.
#pragma once

namespace feedloop::thermal {

struct PidParams {
  double kp = 22.2, ki = 1.08, kd = 114.0;  // Marlin's default hotend gains (per 255 of power)
  double max_power = 1.0;                   // clamp of the output, 0 < max_power <= 1
  double smooth_time_s = 1.0;               // derivative smoothing (Klipper's smooth_time)
};

class HeaterPid {
 public:
  explicit HeaterPid(const PidParams& p = {}) : p_(p) {}
  // One update at time t_s with the measured temperature; returns the power in [0, max_power].
  double update(double t_s, double temp_c, double target_c);
  void reset();
  const PidParams& params() const { return p_; }
  void set_params(const PidParams& p) {
    p_ = p;
    reset();
  }
  double integral() const { return integ_; }

 private:
  PidParams p_;
  bool have_prev_ = false;
  double prev_t_s_ = 0.0, prev_temp_c_ = 0.0, deriv_c_s_ = 0.0, integ_ = 0.0;
};

}  // namespace feedloop::thermal
