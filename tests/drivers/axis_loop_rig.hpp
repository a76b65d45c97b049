// A test rig for the device loop (drivers/device/axis_loop.hpp) without the virtual MCU: a
// stepper that executes the host's feedforward steps plus the loop's extra steps, a belt (spring)
// to a carriage with viscous and Coulomb friction, and a linear encoder. The loop's deflection
// model knows the spring and the viscous term, not the friction (the effect the model lacks).
// Faults can be injected: a lost step cycle (the rotor falls back 4 full steps), an encoder
// glitch, a blocked carriage, a gap in the ticks (the MCU busy elsewhere). Plain double precision,
// 5 us integration step, MCU clock 20 MHz.
#pragma once

#include <algorithm>  // std::min
#include <cmath>
#include <cstdint>
#include <vector>

#include "drivers/device/axis_loop.hpp"

namespace feedloop::testing {

struct RigParams {
  double clock_hz = 20e6;
  double control_hz = 1000.0;
  double step_nm = 5000.0;          // 5 um per microstep
  double count_nm = 490.0;          // encoder resolution (AS5311)
  double mass_kg = 0.45;
  double belt_n_m = 110000.0;
  double damping_n_s_m = 200.0;      // damping ratio 0.45
  double friction_n = 4.0;          // Coulomb friction the loop's model lacks
  double h_s = 5e-6;
  // The move: 0 -> distance at cruise speed with a trapezoid, then hold.
  double distance_mm = 20.0;
  double speed_mm_s = 100.0;
  double accel_mm_s2 = 2000.0;
  double start_s = 0.01;
  double knot_period_s = 1e-3;      // r(t) knots every ms (PWL error a dt^2 / 8 = 0.25 um)
  bool loop_enabled = true;
  // The host's steps come from a model inverse that knows the plant (the LPV feedforward's role):
  // they lead r by the belt's stretch, m a + c v + F sgn(v) over k; else they follow r rigidly.
  bool inverse_feedforward = false;
  float kp = 0.5f;
  float ki_per_s = 40.0f;
};

class LoopRig {
 public:
  explicit LoopRig(const RigParams& p) : p_(p) {
    loop_.init(static_cast<float>(p.clock_hz));
    params_.enabled = true;
    params_.period_ticks = static_cast<uint32_t>(std::llround(p.clock_hz / p.control_hz));
    params_.nm_per_count_q16 = static_cast<uint32_t>(std::llround(p.count_nm * 65536.0));
    params_.nm_per_step_q16 = static_cast<uint32_t>(std::llround(p.step_nm * 65536.0));
    params_.kp = p.loop_enabled ? p.kp : 0.0f;
    params_.ki_per_s = p.loop_enabled ? p.ki_per_s : 0.0f;
    params_.deflection_s2 = static_cast<float>(p.mass_kg / p.belt_n_m);
    params_.deflection_s = static_cast<float>(p.damping_n_s_m / p.belt_n_m);
    params_.slip_cycle_nm = static_cast<float>(4.0 * 16.0 * p.step_nm);  // 4 full steps of 16 microsteps
    params_.slip_threshold_nm = 0.375f * params_.slip_cycle_nm;           // 120 um
    params_.report_every_ticks = 0;
  }

  device::LoopParams& params() { return params_; }
  device::AxisLoop& loop() { return loop_; }
  const RigParams& rig() const { return p_; }

  // Desired carriage position (mm) of the trapezoid move at t.
  double r_mm(double t) const {
    const double tt = t - p_.start_s;
    if (tt <= 0) return 0.0;
    const double v = p_.speed_mm_s, a = p_.accel_mm_s2, d = p_.distance_mm;
    double ta = v / a, da = 0.5 * a * ta * ta;
    double vc = v;
    if (2 * da > d) {
      ta = std::sqrt(d / a);
      da = d / 2;
      vc = a * ta;
    }
    const double tc = (d - 2 * da) / vc;
    if (tt < ta) return 0.5 * a * tt * tt;
    if (tt < ta + tc) return da + vc * (tt - ta);
    const double td = tt - ta - tc;
    if (td < ta) return da + vc * tc + vc * td - 0.5 * a * td * td;
    return d;
  }
  double move_end_s() const {
    const double v = p_.speed_mm_s, a = p_.accel_mm_s2, d = p_.distance_mm;
    const double ta = v / a;
    if (v * ta > d) return p_.start_s + 2 * std::sqrt(d / a);
    return p_.start_s + 2 * ta + (d - v * ta) / v;
  }

  // The inverse's lead of the motor over r at t (mm): the spring force that moves the carriage
  // along r against its inertia, damping and friction.
  double feedforward_lead_mm(double t) const {
    constexpr double h = 1e-4;
    const double v = (r_mm(t + h) - r_mm(t - h)) / (2 * h) * 1e-3;                   // m/s
    const double a = (r_mm(t + h) - 2 * r_mm(t) + r_mm(t - h)) / (h * h) * 1e-3;     // m/s^2
    const double f = p_.mass_kg * a + p_.damping_n_s_m * v + (std::abs(v) > 1e-6 ? (v > 0 ? 1 : -1) * p_.friction_n : 0.0);
    return f / p_.belt_n_m * 1e3;
  }

  int64_t clock_at(double t) const { return static_cast<int64_t>(std::llround(t * p_.clock_hz)); }

  // Activates the loop at t_s; r(t) knots are streamed 100 ms ahead (like the host's
  // queue_ahead_ms) up to knots_until_s.
  void start(double t_s, double knots_until_s) {
    loop_.stage(params_, clock_at(t_s));
    knots_end_s_ = knots_until_s;
    queue_knots_until(std::min(knots_end_s_, t_ + 0.1));
  }
  void queue_knots_until(double t_end_s) {
    for (;;) {
      const double t = static_cast<double>(next_knot_) * p_.knot_period_s;
      if (t > t_end_s + 1e-9) break;
      loop_.push_target({clock_at(t), std::llround(r_mm(t) * 1e6)});
      ++next_knot_;
    }
  }

  // Runs the plant and the loop to t_end. The host's feedforward steps follow r(t) rigidly
  // (round(r / step)) while host_steps_on; ticks happen on the loop's grid unless skipped.
  void run_until(double t_end) {
    while (t_ + p_.h_s <= t_end + 1e-12) {
      const int64_t c_now = clock_at(t_);
      queue_knots_until(std::min(knots_end_s_, t_ + 0.1));
      // Loop tick at the current instant (the encoder sampled now).
      const int64_t tick_clock = loop_.next_tick_clock();
      const bool busy = t_ >= skip_from_s_ && t_ < skip_until_s_;  // the MCU is busy: no tick
      if (tick_clock != device::AxisLoop::kNever && tick_clock <= c_now && !busy) tick(c_now);
      const double t_next = t_ + p_.h_s;
      const int64_t c_next = clock_at(t_next);
      // Device (extra) steps due in (t_, t_next].
      while (extra_left_ != 0 && extra_next_clock_ <= c_next) {
        const int dir = extra_left_ > 0 ? 1 : -1;
        motor_steps_ += dir;
        device_steps_ += dir;
        extra_left_ -= dir;
        ++extra_k_;
        extra_next_clock_ = extra_start_ + static_cast<int64_t>((extra_k_ + 0.5) * extra_span_ / extra_n_);
      }
      // Host feedforward steps.
      if (host_steps_on_) {
        const double u_mm = r_mm(t_next) + (p_.inverse_feedforward ? feedforward_lead_mm(t_next) : 0.0);
        const int64_t want = std::llround(u_mm * 1e6 / p_.step_nm);
        motor_steps_ += want - host_steps_;
        host_steps_ = want;
      }
      integrate(p_.h_s);
      t_ = t_next;
      motor_log_.push_back(motor_mm());
    }
  }

  void tick(int64_t clock) {
    device::LoopTickIn in;
    in.clock = clock;
    in.encoder_counts = encoder_counts();
    in.motor_steps = motor_steps_;
    in.device_steps = device_steps_;
    device::LoopTickOut out;
    loop_.tick(in, out);
    u_log_.push_back({t_, loop_.pi().output_nm(), loop_.last_error_nm()});
    if (out.flush_host_steps) host_steps_on_ = false;
    if (out.stopped) stopped_at_s_ = t_;
    step_fraction_ = out.step_fraction;  // the driver's current phase below a step (sub_step_trim)
    extra_left_ = out.extra_steps;
    extra_n_ = out.extra_steps < 0 ? -out.extra_steps : out.extra_steps;
    extra_start_ = clock;
    extra_span_ = static_cast<double>(out.over_ticks);
    extra_k_ = 0;
    extra_next_clock_ = extra_start_ + static_cast<int64_t>(0.5 * extra_span_ / (extra_n_ > 0 ? extra_n_ : 1));
    device::LoopEvent e;
    while (loop_.pop_event(e)) events_.push_back(e);
  }

  int64_t encoder_counts() const {
    return static_cast<int64_t>(std::floor((x_c_ + glitch_m_) * 1e9 / p_.count_nm));
  }
  double carriage_mm() const { return x_c_ * 1e3; }
  double motor_mm() const {
    return ((motor_steps_ + step_fraction_) * p_.step_nm * 1e-9 - lost_m_) * 1e3;
  }
  double error_mm(double t) const { return r_mm(t) - carriage_mm(); }
  double t() const { return t_; }

  // Faults.
  void lose_cycle(int dir) { lost_m_ += dir * 4.0 * 16.0 * p_.step_nm * 1e-9; }
  void set_glitch_mm(double g) { glitch_m_ = g * 1e-3; }
  void block_carriage(bool on) { blocked_ = on; }
  void skip_ticks(double from_s, double until_s) {
    skip_from_s_ = from_s;
    skip_until_s_ = until_s;
  }

  struct ULog {
    double t;
    float u_nm, e_nm;
  };
  const std::vector<ULog>& u_log() const { return u_log_; }
  const std::vector<double>& motor_log() const { return motor_log_; }  // every h_s
  const std::vector<device::LoopEvent>& events() const { return events_; }
  int count(device::LoopEventKind k) const {
    int n = 0;
    for (const auto& e : events_) n += e.kind == k;
    return n;
  }
  double stopped_at_s() const { return stopped_at_s_; }
  int64_t device_steps() const { return device_steps_; }

 private:
  void integrate(double h) {
    if (blocked_) {
      v_c_ = 0.0;
      return;
    }
    const double m = (motor_steps_ + step_fraction_) * p_.step_nm * 1e-9 - lost_m_;
    const double f_spring = p_.belt_n_m * (m - x_c_) - p_.damping_n_s_m * v_c_;
    // Coulomb friction with sticking.
    double f = f_spring;
    if (std::abs(v_c_) < 1e-6 && std::abs(f_spring) <= p_.friction_n) {
      v_c_ = 0.0;
      return;
    }
    f -= (v_c_ > 0 || (v_c_ == 0 && f_spring > 0) ? 1.0 : -1.0) * p_.friction_n;
    const double v_new = v_c_ + h * f / p_.mass_kg;
    // Friction does not reverse the motion within a step.
    v_c_ = (v_c_ != 0.0 && (v_new > 0) != (v_c_ > 0)) ? 0.0 : v_new;
    x_c_ += h * v_c_;
  }

  RigParams p_;
  device::LoopParams params_{};
  device::AxisLoop loop_;
  double t_ = 0.0;
  int64_t next_knot_ = 0;
  double knots_end_s_ = 0.0;
  double x_c_ = 0.0, v_c_ = 0.0, lost_m_ = 0.0, glitch_m_ = 0.0;
  bool blocked_ = false;
  int64_t motor_steps_ = 0, host_steps_ = 0, device_steps_ = 0;
  double step_fraction_ = 0.0;
  bool host_steps_on_ = true;
  int32_t extra_left_ = 0, extra_n_ = 0, extra_k_ = 0;
  int64_t extra_start_ = 0, extra_next_clock_ = 0;
  double extra_span_ = 0.0;
  double skip_from_s_ = -1.0, skip_until_s_ = -1.0;
  double stopped_at_s_ = -1.0;
  std::vector<ULog> u_log_;
  std::vector<double> motor_log_;
  std::vector<device::LoopEvent> events_;
};

}  // namespace feedloop::testing
