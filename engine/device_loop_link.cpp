// The host's side of the device loop (see device_loop_link.hpp).
#include "engine/device_loop_link.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "drivers/device/target_queue.hpp"
#include "engine/control_config.hpp"

namespace feedloop::engine {

// The config check bounds stepgen.queue_ahead_ms by the device's knot queue
// (config/check_machine.cpp).
static_assert(config::kDeviceTargetKnots == device::TargetQueue::kCapacity);

namespace {
uint32_t q16(double nm) {
  return static_cast<uint32_t>(std::llround(nm * 65536.0));
}
}  // namespace

device::LoopParams DeviceLoopLink::params_from_config(const config::MachineConfig& cfg, int joint,
                                                      double mm_per_count, double mm_per_step,
                                                      double clock_hz) {
  device::LoopParams p;
  const config::ControlConfig& c = cfg.control;
  if (c.mode != config::ControlMode::pi || c.loop != config::ControlLoop::device) return p;
  if (joint < 0 || joint >= 3 || !(mm_per_count > 0.0) || !(mm_per_step > 0.0)) return p;
  const auto names = joint_names(cfg);
  const std::string& name = names[static_cast<size_t>(joint)];
  const config::AxisConfig* axis = cfg.axis(name);
  const bool delta = cfg.kinematics == config::Kinematics::delta;
  if (!delta && (axis == nullptr || !axis->encoder))
    return p;  // the simulated delta has carriage encoders
  p.enabled = true;
  p.period_ticks = static_cast<uint32_t>(std::llround(clock_hz / c.device_rate_hz));
  p.nm_per_count_q16 = q16(mm_per_count * 1e6);
  p.nm_per_step_q16 = q16(mm_per_step * 1e6);
  const config::AxisGainsConfig g = c.gains_for(name);
  p.kp = static_cast<float>(g.kp);  // thesis Sect. 5: P = 0.5, I = 20
  p.ki_per_s = static_cast<float>(g.ki_per_s);
  // The correction may take up to the following-error limit; it changes by at most
  // max_correction_mm_s (thesis: clamped "to keep the motor out of resonance").
  p.max_correction_nm = static_cast<float>(c.max_following_error_mm * 1e6);
  p.max_correction_rate_nm_s = static_cast<float>(c.max_correction_mm_s * 1e6);
  p.max_following_error_nm = static_cast<float>(c.max_following_error_mm * 1e6);
  // Encoder plausibility: the host guard's limits (engine/control_config.hpp), at least 4 counts
  // of margin.
  const control::EncoderGuardParams guard = encoder_guard_params_from_config(cfg, name);
  p.max_speed_nm_s = static_cast<float>(guard.max_speed_mm_s * 1e6);
  p.encoder_margin_nm = static_cast<float>(std::max(guard.jump_margin_mm, 4.0 * mm_per_count) * 1e6);
  p.encoder_reject_limit = static_cast<uint32_t>(guard.reject_limit);
  p.slip_threshold_nm = static_cast<float>(c.skipped_step_threshold_mm * 1e6);
  // A slip is an offset that stays; the belt's ringing (Y: 21 Hz, thesis Table 4) crosses zero
  // every ~24 ms. 30 ms of MCU time beyond the threshold tells the two apart.
  p.slip_settle_s = 0.03f;
  const double a_max_mm_s2 = axis != nullptr ? axis->max_accel_mm_s2 : cfg.planner.max_accel_mm_s2;
  p.stop_decel_nm_s2 = static_cast<float>(a_max_mm_s2 * 1e6);
  if (const config::GantryModelConfig* gm = cfg.model.gantry_for(name); gm != nullptr && !delta) {
    // A stepper's torque law repeats every 4 full steps: 2 pi r / n_r (thesis Eq. 2).
    const double cycle_mm =
        2.0 * std::numbers::pi * gm->stepper.pulley_radius_mm / gm->stepper.rotor_teeth;
    if (cycle_mm > 2.0 * c.skipped_step_threshold_mm)
      p.slip_cycle_nm = static_cast<float>(cycle_mm * 1e6);
    // Motor - carriage while accelerating and at speed (Eq. 13's static deflection): the belt
    // stretches by m2 a / k2, and the driver's field lags by c1 / k1 plus the belt's viscous c2 /
    // k2.
    p.deflection_s2 = static_cast<float>(gm->m2_kg / gm->k2_n_per_m);
    // With the field's own lag (field_lag_ms) c1 damps the load angle, not the speed: the field
    // lags by that, and the rotor behind it by the carriage's drag c2 / k1.
    p.deflection_s = static_cast<float>(
        gm->field_lag_ms > 0.0
            ? gm->field_lag_ms * 1e-3 + gm->c2_ns_per_m / gm->k1_n_per_m +
                  gm->c2_ns_per_m / gm->k2_n_per_m
            : gm->c1_ns_per_m / gm->k1_n_per_m + gm->c2_ns_per_m / gm->k2_n_per_m);
  }
  // Behind the model inverse the host's steps already lead r by the deflection a better model
  // expects (the belt's position and direction dependence, the identified friction): the slip
  // check takes that lead (the host loop's detector does the same, engine/servo_control.cpp).
  p.deflection_from_host_steps = cfg.feedforward.type == config::FeedforwardType::lpv;
  p.sub_step_trim = cfg.control.sub_step_trim;
  p.report_every_ticks =
      static_cast<uint32_t>(std::max(1.0, std::round(c.device_rate_hz / 100.0)));  // 100 Hz
  // A delta carriage's correction acts through its electrical part, a 46-65 Hz mode with zeta
  // 0.048 and |G| up to 48 (delta paper Table I; docs/decisions.md): a correction step toggling
  // back and forth at half a step held a 0.6 mm limit cycle there. A reversal waits for half a
  // step more. The gantry's modes are damped: plain rounding, as the thesis's loop steps.
  p.reversal_hysteresis_steps = delta ? 0.5f : 0.0f;
  return p;
}

void DeviceLoopLink::set_joint(int joint, uint8_t motor, const device::LoopParams& params) {
  Joint& j = j_[static_cast<size_t>(joint)];
  j.params = params;
  j.motor = motor;
  j.mm_per_count = params.nm_per_count_q16 / 65536.0 * 1e-6;
  j.telemetry.enabled = params.enabled;
  // Knots within 0.5 um of every sample, at least one every 10 ms (r's horizon keeps up).
  const double clock_hz = params.period_ticks > 0 ? 1.0 : 1.0;
  (void)clock_hz;
}

bool DeviceLoopLink::any_enabled() const {
  for (const Joint& j : j_)
    if (j.params.enabled) return true;
  return false;
}

namespace {
// CONFIGURE_LOOP for `motor` with `params`, active at activation_clock.
void send_configure_loop(drivers::McuSession& session, uint8_t motor, const device::LoopParams& params,
                         int64_t activation_clock) {
  protocol::ConfigureLoopMsg m;
  m.axis = motor;
  m.activation_clock = activation_clock;
  m.params = params;
  uint8_t buf[protocol::kMaxPayload];
  const size_t n = protocol::encode_configure_loop(m, buf, sizeof buf);
  if (n > 0) session.queue_message(buf, n);
}
}  // namespace

void DeviceLoopLink::configure(int joint, drivers::McuSession& session, int64_t activation_clock) {
  Joint& j = j_[static_cast<size_t>(joint)];
  if (!j.params.enabled) return;
  send_configure_loop(session, j.motor, j.params, activation_clock);
  const double ticks_per_ms = static_cast<double>(session.mcu_clock_hz()) * 1e-3;
  j.compressor.configure(config::kDeviceTargetToleranceMm * 1e6,
                         static_cast<int64_t>(10.0 * ticks_per_ms));
  j.pending_count = 0;
  j.last_clock = INT64_MIN;
  j.telemetry = DeviceLoopTelemetry{};  // the MCU's loop starts afresh (its counters too)
  j.telemetry.enabled = true;
}

void DeviceLoopLink::disable(int joint, drivers::McuSession& session, int64_t activation_clock) {
  Joint& j = j_[static_cast<size_t>(joint)];
  if (!j.params.enabled) return;
  device::LoopParams off = j.params;
  off.enabled = false;
  send_configure_loop(session, j.motor, off, activation_clock);
  j.pending_count = 0;
  j.last_clock = INT64_MIN;
}

void DeviceLoopLink::push_target(int joint, drivers::McuSession& session, int64_t clock,
                                 double r_mm) {
  Joint& j = j_[static_cast<size_t>(joint)];
  if (!j.params.enabled || clock <= j.last_clock || !std::isfinite(r_mm)) return;
  j.last_clock = clock;
  device::TargetKnot k;
  if (j.compressor.push(clock, r_mm * 1e6, k)) {
    j.pending[static_cast<size_t>(j.pending_count++)] = k;
    if (j.pending_count == kKnotsPerMessage) send_pending(j, session);
  }
}

void DeviceLoopLink::flush(int joint, drivers::McuSession& session, bool end_of_motion) {
  Joint& j = j_[static_cast<size_t>(joint)];
  if (!j.params.enabled) return;
  device::TargetKnot k;
  if (end_of_motion && j.compressor.flush(k)) {
    j.pending[static_cast<size_t>(j.pending_count++)] = k;
    if (j.pending_count == kKnotsPerMessage) send_pending(j, session);
  }
  if (j.pending_count > 0) send_pending(j, session);
}

void DeviceLoopLink::send_pending(Joint& j, drivers::McuSession& session) {
  uint8_t buf[protocol::kMaxPayload];
  const size_t n =
      protocol::encode_queue_target(j.motor, j.pending.data(), j.pending_count, buf, sizeof buf);
  if (n > 0) session.queue_message(buf, n);
  j.pending_count = 0;
}

size_t DeviceLoopLink::collect(drivers::McuSession& session, int mcu,
                               const std::array<int, kJoints>& joint_mcu,
                               const std::array<int, kJoints>& joint_motor, JointEvent* out,
                               size_t cap, DeviceLoopReport* reports, size_t reports_cap,
                               size_t* n_reports) {
  auto joint_of = [&](uint8_t motor) {
    for (int j = 0; j < kJoints; ++j)
      if (joint_mcu[static_cast<size_t>(j)] == mcu && joint_motor[static_cast<size_t>(j)] == motor)
        return j;
    return -1;
  };
  protocol::LoopReportMsg msgs[16];
  for (size_t n; (n = session.take_loop_reports(msgs, 16)) > 0;) {
    for (size_t i = 0; i < n; ++i) {
      const int joint = joint_of(msgs[i].axis);
      if (joint < 0) continue;
      const device::LoopReport& r = msgs[i].report;
      DeviceLoopReport d;
      d.joint = joint;
      d.clock = r.clock;
      d.state = static_cast<uint8_t>(r.state);
      d.e_mm = static_cast<double>(r.e_nm) * 1e-6;
      d.y_mm = static_cast<double>(r.y_nm) * 1e-6;
      d.correction_mm = static_cast<double>(r.u_nm) * 1e-6;
      d.tick_cost = r.max_tick_cost;
      d.tick_cost_us = r.max_tick_cost * 1e-3;  // the virtual MCU measures ns
      d.ticks = r.ticks;
      d.deadline_misses = r.deadline_misses;
      d.encoder_rejects = r.encoder_rejects;
      d.slips = r.slips;
      j_[static_cast<size_t>(joint)].telemetry.add(d);
      if (reports != nullptr && n_reports != nullptr && *n_reports < reports_cap)
        reports[(*n_reports)++] = d;
      else
        ++reports_overflow_;
    }
  }
  size_t k = 0;
  protocol::LoopEventMsg events[16];
  for (size_t n; (n = session.take_loop_events(events, 16)) > 0;) {
    for (size_t i = 0; i < n; ++i) {
      const int joint = joint_of(events[i].axis);
      if (joint < 0 || k >= cap) continue;
      out[k].joint = joint;
      out[k].event = events[i].event;
      ++k;
    }
  }
  return k;
}

std::string describe_loop_event(const std::string& joint, const device::LoopEvent& e) {
  char buf[192];
  using K = device::LoopEventKind;
  switch (e.kind) {
    case K::kSlip:
      std::snprintf(buf, sizeof buf,
                    "%s: lost steps: %lld torque cycle(s) (%.3f mm), made up by the device loop",
                    joint.c_str(), static_cast<long long>(e.a), static_cast<double>(e.b) * 1e-6);
      break;
    case K::kEncoderReject:
      std::snprintf(
          buf, sizeof buf, "%s: encoder sample ignored: moved %.3f mm where %.3f mm was possible",
          joint.c_str(), static_cast<double>(e.a) * 1e-6, static_cast<double>(e.b) * 1e-6);
      break;
    case K::kEncoderFault:
      std::snprintf(buf, sizeof buf,
                    "%s: encoder fault: moved %.3f mm where %.3f mm was possible; controlled stop",
                    joint.c_str(), static_cast<double>(e.a) * 1e-6,
                    static_cast<double>(e.b) * 1e-6);
      break;
    case K::kFollowingError:
      std::snprintf(buf, sizeof buf, "%s: following error %.3f mm (limit %.3f mm); controlled stop",
                    joint.c_str(), static_cast<double>(e.a) * 1e-6,
                    static_cast<double>(e.b) * 1e-6);
      break;
    case K::kStopStarted:
      std::snprintf(buf, sizeof buf, "%s: device loop: controlled stop (%s) from %.1f mm/s",
                    joint.c_str(), protocol::stop_reason_name(static_cast<device::StopReason>(e.a)),
                    static_cast<double>(e.b) * 1e-6);
      break;
    default:
      std::snprintf(buf, sizeof buf, "%s: device loop: %s (%lld, %lld)", joint.c_str(),
                    protocol::loop_event_name(e.kind), static_cast<long long>(e.a),
                    static_cast<long long>(e.b));
  }
  return buf;
}

}  // namespace feedloop::engine
