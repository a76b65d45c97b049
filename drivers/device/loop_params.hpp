// Parameters of the device-side fast loop of one axis (drivers/device/axis_loop.hpp), as the host
// sends them in CONFIGURE_LOOP (docs/protocol.md, "Protocol v2: the device loop"). Plain data, no
// dependencies: the loop library, the wire codec and the host all use this struct.
//
// Units on the device: positions in nanometres (int64 absolute, float for differences), time in
// MCU clock ticks (int64), rates per second. Positions are relative to the power-on zero of the
// step counter and of the encoder, which coincide (both count from where the carriage was).
#pragma once

#include <cstdint>

namespace feedloop::device {

struct LoopParams {
  bool enabled = false;             // false: the device executes the host's steps only (protocol v1)
  uint32_t period_ticks = 0;        // control period in MCU ticks (1 kHz default: clock_hz / 1000)

  // Geometry (Q16.16 fixed point, nm per unit * 65536).
  uint32_t nm_per_count_q16 = 0;    // encoder count -> nm (0.49 um -> 490 * 65536)
  uint32_t nm_per_step_q16 = 0;     // motor (micro)step -> nm

  // PI, thesis Sect. 4.6: u[k] = K_P e[k] + K_I sum_{m<=k} e[m] (t[m] - t[m-1]).
  float kp = 0.5f;                  // nm of correction per nm of error
  float ki_per_s = 20.0f;           // 1/s
  float max_correction_nm = 2.0e6f; // output clamp |u| <= this (anti-windup: conditional integration)
  float max_correction_rate_nm_s = 50.0e6f;  // extra steps per period <= this * T / step (thesis: clamped "to keep the motor from reaching resonance")

  // Supervision.
  float max_following_error_nm = 2.0e6f;  // |r - y| beyond this: trip (controlled stop)
  float max_speed_nm_s = 500.0e6f;        // encoder plausibility: |y - y_good| <= v_max (t - t_good) + margin
  float encoder_margin_nm = 50.0e3f;      //   (noise, quantisation, one step of ringing)
  uint32_t encoder_reject_limit = 3;      // this many implausible samples in a row: trip

  // Skipped steps (control/lost_step_detector.hpp on the device): d = motor - y - deflection - S.
  float slip_threshold_nm = 250.0e3f;     // |d| beyond this: a slip is suspected
  float slip_cycle_nm = 0.0f;             // 4 full steps (the torque law's period); 0: not rounded
  float slip_settle_s = 0.010f;           // MCU time |d| must stay beyond the threshold (the ringing decays)

  // Small model of the motor-to-carriage deflection (belt stretch), motor - carriage =
  //   deflection_s2 * a_ref + deflection_s * v_ref   (a_ref filtered from r's slope).
  float deflection_s2 = 0.0f;             // m / k (s^2)
  float deflection_s = 0.0f;              // c / k (s)
  float accel_filter_s = 0.005f;          // time constant of the a_ref filter
  // The host's steps come from a model inverse (the LPV feedforward), which already leads r by
  // the deflection its better model expects (position- and direction-dependent belt, friction):
  // the expected deflection is then the host's steps - r, and the two terms above are unused.
  bool deflection_from_host_steps = false;

  // Controlled stop (watchdog, trips): decelerate from r's speed at this rate.
  float stop_decel_nm_s2 = 3.0e9f;        // 3000 mm/s^2
  uint32_t horizon_margin_ticks = 0;      // start the stop when r's queue ends within this (0: 20 ms)

  uint32_t report_every_ticks = 10;       // LOOP_REPORT every N ticks (0: none)

  // Correction steps: rounded, but a step against the last one waits until the correction is
  // this many steps beyond the rounding threshold (0: plain rounding). A lightly damped carriage
  // (the delta's electrical mode) turns a step toggling at half a step into a limit cycle.
  float reversal_hysteresis_steps = 0.0f;

  // The correction below one step goes to the motor port as a fraction of a step
  // (MotorPort::set_step_fraction: a driver with direct current control), so the carriage can be
  // held on the encoder within a count instead of within half a step (issue 16's return after a
  // pause). Without such a driver it changes nothing.
  bool sub_step_trim = false;
};

// What is wrong with a parameter set (validate_loop_params); kOk when usable.
enum class LoopParamError : uint8_t {
  kOk = 0,
  kPeriod = 1,        // period_ticks == 0
  kGeometry = 2,      // nm_per_count_q16 or nm_per_step_q16 == 0
  kGains = 3,         // kp, ki < 0 or not finite
  kLimits = 4,        // a clamp, rate, trip or speed not > 0
  kSlip = 5,          // threshold not > 0, or a cycle not > 2 x threshold
  kStop = 6,          // stop_decel_nm_s2 not > 0
  kModel = 7,         // deflection terms or filter not finite / filter < 0
  kHysteresis = 8,    // reversal_hysteresis_steps not in [0, 4]
};

const char* loop_param_error_name(LoopParamError e);

// Checks the fields that matter when enabled (a disabled set is always valid).
LoopParamError validate_loop_params(const LoopParams& p);

}  // namespace feedloop::device
