// The device loop inside the virtual MCU, driven through the real host path (McuSession over the
// mock transport, protocol v2 messages): the thesis X axis (sim::GantryAxis) with Coulomb friction
// and a 0.3 % scale error, which the loop's model does not know. The host streams rigid
// feedforward steps (r / mm_per_step) and r(t) through the bounded-error compressor, 100 ms ahead.
// Also: the host going silent ends in a controlled stop, and version negotiation both ways.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>  // memcpy
#include <memory>
#include <vector>

#include "drivers/device/virtual_mcu.hpp"
#include "drivers/host/mcu_session.hpp"
#include "drivers/protocol/loop_messages.hpp"
#include "drivers/protocol/target_codec.hpp"
#include "drivers/stepgen/run_codec.hpp"
#include "drivers/transport/mock_transport.hpp"
#include "sim/gantry_axis.hpp"

using namespace feedloop;
using drivers::McuSession;
using drivers::McuSessionParams;
using drivers::McuState;
using drivers::MockTransport;

namespace {

constexpr double kHz = 20e6;

// 0 -> d mm trapezoid starting at t0.
struct Move {
  double t0 = 0.5, d = 30.0, v = 100.0, a = 2000.0;
  double r(double t) const {
    const double tt = t - t0;
    if (tt <= 0) return 0.0;
    const double ta = v / a, da = 0.5 * a * ta * ta, tc = (d - 2 * da) / v;
    if (tt < ta) return 0.5 * a * tt * tt;
    if (tt < ta + tc) return da + v * (tt - ta);
    const double td = tt - ta - tc;
    if (td < ta) return da + v * tc + v * td - 0.5 * a * td * td;
    return d;
  }
  double end() const { return t0 + 2 * v / a + (d - v * v / a) / v; }
  // Time r crosses x (monotone move), by bisection.
  double time_at(double x) const {
    double lo = t0, hi = end();
    for (int i = 0; i < 60; ++i) {
      const double m = 0.5 * (lo + hi);
      (r(m) < x ? lo : hi) = m;
    }
    return hi;
  }
};

sim::GantryAxisParams plant_params() {
  sim::GantryAxisParams p = sim::thesis_x_axis();
  p.effects.coulomb_friction.enabled = true;
  p.effects.coulomb_friction.force_n = 3.0;
  p.effects.scale_error.enabled = true;
  p.effects.scale_error.scale = 1.003;
  return p;
}

struct Rig {
  std::unique_ptr<sim::GantryAxis> axis;
  std::unique_ptr<device::VirtualMcu> mcu;
  std::unique_ptr<MockTransport> transport;
  std::unique_ptr<McuSession> session;
  Move move;
  double now = 0.0;
  // Streaming state.
  double steps_until_s = 0.0, knots_until_s = 0.0;
  int64_t next_step = 0, last_step_clock = 0;
  protocol::TargetCompressor compressor;
  std::vector<device::TargetKnot> pending_knots;
  bool streaming = true;
  std::vector<protocol::LoopEventMsg> events;
  std::vector<protocol::LoopReportMsg> reports;

  explicit Rig(device::VirtualMcuParams mp = {}, McuSessionParams sp = {}) {
    axis = std::make_unique<sim::GantryAxis>(std::move(sim::GantryAxis::create(plant_params()).value()));
    mcu = std::make_unique<device::VirtualMcu>(mp, axis.get());
    transport = std::make_unique<MockTransport>(*mcu, drivers::MockFaults{}, "x");
    sp.name = "x";
    sp.watchdog_s = 0.2;
    session = std::make_unique<McuSession>(sp, *transport);
    compressor.configure(500.0, static_cast<int64_t>(0.02 * kHz));  // 0.5 um, a knot at least every 20 ms
  }
  int64_t clock(double t) const { return static_cast<int64_t>(std::llround(t * kHz)); }

  bool start() {
    if (!session->start(now).ok()) return false;
    while (now < 0.2 && !session->ready() && session->state() != McuState::kFailed) advance(now + 1e-3);
    if (!session->ready()) return false;
    session->set_enabled(true);
    advance(now + 0.01);
    return true;
  }

  void configure_loop(double t_activate, float kp = 0.5f) {
    protocol::ConfigureLoopMsg m;
    device::LoopParams& p = m.params;
    const sim::GantryAxisParams gp = plant_params();
    p.enabled = true;
    p.period_ticks = static_cast<uint32_t>(kHz / 1000);
    p.nm_per_count_q16 = static_cast<uint32_t>(std::llround(axis->encoder_mm_per_count() * 1e6 * 65536));
    p.nm_per_step_q16 = static_cast<uint32_t>(std::llround(axis->mm_per_step() * 1e6 * 65536));
    p.kp = kp;  // thesis Sect. 5: P = 0.5, I = 20
    p.ki_per_s = 20.0f;
    p.slip_cycle_nm = static_cast<float>(4 * gp.microsteps * axis->mm_per_step() * 1e6);
    p.deflection_s2 = static_cast<float>(gp.carriage_mass_kg / gp.belt_stiffness_n_m);
    // Motor count - carriage at speed v: the driver's field lags the steps by tau = c1 / k1
    // (sim/gantry_axis.hpp) and the belt stretches by c2 v / k2. Friction is not in the model.
    p.deflection_s = static_cast<float>(gp.motor_damping_n_s_m / gp.motor_stiffness_n_m +
                                        gp.bearing_damping_n_s_m / gp.belt_stiffness_n_m);
    p.stop_decel_nm_s2 = 2.0e9f;
    m.activation_clock = clock(t_activate);
    uint8_t buf[protocol::kMaxPayload];
    const size_t n = protocol::encode_configure_loop(m, buf, sizeof buf);
    ASSERT_GT(n, 0u);
    session->queue_message(buf, n);
  }

  // Keeps steps and r(t) knots queued 100 ms ahead of now.
  void stream() {
    const double ahead = now + 0.1;
    // Steps, in 2 ms batches of single-step runs (the step of threshold (n + 1/2) mm/step).
    const double mm_per_step = axis->mm_per_step();
    while (steps_until_s < ahead && steps_until_s < move.end() + 0.002) {
      const double t_end = steps_until_s + 0.002;
      uint8_t body[protocol::kMaxPayload];
      stepgen::RunEncoder enc;
      const int64_t first = next_step == 0 ? clock(move.t0) : last_step_clock;
      enc.begin(body, sizeof body - 4, static_cast<uint64_t>(first));
      int64_t prev = first;
      int count = 0;
      for (;;) {
        const double x = (static_cast<double>(next_step) + 0.5) * mm_per_step;
        if (x >= move.d) break;
        const double ts = move.time_at(x);
        if (ts > t_end) break;
        const int64_t c = clock(ts);
        stepgen::StepRun run;
        run.interval_ticks = c - prev;
        run.count = 1;
        run.direction = 1;
        if (!enc.append(run)) break;
        prev = c;
        ++next_step;
        ++count;
      }
      if (count > 0) {
        uint8_t msg[protocol::kMaxPayload];
        msg[0] = static_cast<uint8_t>(protocol::MsgType::kQueueSteps);
        msg[1] = 0;
        std::memcpy(msg + 2, body, enc.size());
        session->queue_message(msg, 2 + enc.size());
        last_step_clock = prev;
      }
      steps_until_s = t_end;
    }
    // r(t) samples every 1 ms through the compressor.
    while (knots_until_s < ahead) {
      device::TargetKnot k;
      if (compressor.push(clock(knots_until_s), move.r(knots_until_s) * 1e6, k)) pending_knots.push_back(k);
      knots_until_s += 0.001;
    }
    if (!pending_knots.empty()) {
      uint8_t buf[protocol::kMaxPayload];
      const size_t n = protocol::encode_queue_target(0, pending_knots.data(), static_cast<int>(pending_knots.size()), buf, sizeof buf);
      ASSERT_GT(n, 0u);
      session->queue_message(buf, n);
      pending_knots.clear();
    }
  }

  void advance(double until) {
    while (now < until) {
      now += 1e-4;
      if (streaming && session->ready()) stream();
      session->poll(now);
      protocol::LoopEventMsg ev[16];
      for (size_t k = session->take_loop_events(ev, 16), i = 0; i < k; ++i) events.push_back(ev[i]);
      protocol::LoopReportMsg rep[16];
      for (size_t k = session->take_loop_reports(rep, 16), i = 0; i < k; ++i) reports.push_back(rep[i]);
    }
  }
  int count(device::LoopEventKind kind) const {
    int n = 0;
    for (const auto& e : events) n += e.event.kind == kind;
    return n;
  }
};

// |target - carriage| (ground truth) averaged over [t0, t1], sampled every ms.
struct Track {
  double cruise_mm, hold_mm;
};

Track run_move(bool with_loop) {
  Rig rig;
  EXPECT_TRUE(rig.start());
  if (with_loop) rig.configure_loop(0.3);
  double cruise = 0, hold = 0;
  int nc = 0, nh = 0;
  const double ta = rig.move.v / rig.move.a;
  while (rig.now < rig.move.end() + 0.5) {
    rig.advance(rig.now + 0.001);
    rig.axis->advance_to(rig.now);
    const double err = std::abs(rig.move.r(rig.now) - rig.axis->carriage_mm());
    if (rig.now > rig.move.t0 + ta + 0.02 && rig.now < rig.move.end() - ta) {
      cruise += err;
      ++nc;
    }
    if (rig.now > rig.move.end() + 0.4) {
      hold += err;
      ++nh;
    }
  }
  EXPECT_EQ(rig.session->state(), McuState::kReady) << (rig.session->error() ? rig.session->error()->message : "");
  EXPECT_EQ(rig.session->negotiated_version(), protocol::kProtocolVersion);
  std::printf("%s: plant slip events %lld (lost full steps %lld), loop slip events %d\n", with_loop ? "closed" : "open",
              static_cast<long long>(rig.axis->slip_events()), static_cast<long long>(rig.axis->lost_full_steps()),
              rig.count(device::LoopEventKind::kSlip));
  if (with_loop) {
    EXPECT_EQ(rig.count(device::LoopEventKind::kActivated), 1);
    // Every slip of the plant's rotor is reported once (each a 4-full-step cycle).
    EXPECT_EQ(rig.count(device::LoopEventKind::kSlip), rig.axis->slip_events());
    EXPECT_GT(rig.reports.size(), 100u);  // one every 10 ticks
    const auto& last = rig.reports.back().report;
    EXPECT_EQ(last.state, device::LoopState::kRunning);
    EXPECT_NE(last.device_steps, 0);
    EXPECT_GT(last.ticks, 1000u);
    EXPECT_EQ(last.deadline_misses, 0u);
    std::printf("last report: e %.0f nm, y %lld nm, u %.0f nm, loop steps %lld, max tick cost %u ns\n", last.e_nm,
                static_cast<long long>(last.y_nm), last.u_nm, static_cast<long long>(last.device_steps),
                last.max_tick_cost);
  } else {
    EXPECT_EQ(rig.reports.size(), 0u);
  }
  return {cruise / nc, hold / nh};
}

}  // namespace

TEST(VmcuLoop, ClosesTheLoopOnTheSimulatedGantry) {
  const Track open = run_move(false);
  const Track closed = run_move(true);
  std::printf("mean |r - x|: cruise open %.4f mm closed %.4f mm; hold open %.4f mm closed %.4f mm\n", open.cruise_mm,
              closed.cruise_mm, open.hold_mm, closed.hold_mm);
  // 0.3 % scale error over 30 mm = 90 um at the end, plus friction: the loop takes it out.
  EXPECT_GT(open.hold_mm, 0.05);
  EXPECT_LT(closed.hold_mm, 0.2 * open.hold_mm);
  EXPECT_LT(closed.cruise_mm, open.cruise_mm);
}

TEST(VmcuLoop, HostSilentEndsInAControlledStop) {
  Rig rig;
  ASSERT_TRUE(rig.start());
  rig.configure_loop(0.3);
  const double t_silent = rig.move.t0 + 0.15;  // cruising at 100 mm/s
  while (rig.now < t_silent) rig.advance(rig.now + 0.001);
  // The host stops talking (no heartbeats, no steps, no knots): only the device runs on.
  std::vector<double> v;
  rig.mcu->run_until(rig.now);
  rig.axis->advance_to(rig.now);
  double x_prev = rig.axis->carriage_mm();
  for (double t = rig.now + 0.001; t < t_silent + 0.6; t += 0.001) {
    rig.mcu->run_until(t);
    rig.axis->advance_to(t);
    const double x = rig.axis->carriage_mm();
    v.push_back((x - x_prev) / 0.001);
    x_prev = x;
  }
  const auto& st = rig.mcu->status();
  EXPECT_TRUE(st.stopped);
  // The first to notice is the target horizon: r's queue (100 ms ahead) would end while moving, so
  // the stop starts 20 ms before it, ahead of the 200 ms watchdog.
  EXPECT_EQ(st.stop_reason, protocol::McuError::kTargetUnderrun);
  // The ramp: 100 mm/s to 0 at 2000 mm/s^2, not a cliff. The carriage's speed over 1 ms never drops by more than the ramp plus ringing.
  double max_drop = 0;
  size_t i_stop = 0;
  for (size_t i = 1; i < v.size(); ++i) {
    max_drop = std::max(max_drop, v[i - 1] - v[i]);
    if (i_stop == 0 && std::abs(v[i]) < 1.0 && std::abs(v[i - 1]) < 1.0) i_stop = i;
  }
  std::printf("silent host: speed %.1f mm/s when silent, largest 1 ms drop %.1f mm/s, at rest after %zu ms\n", v[0],
              max_drop, i_stop);
  EXPECT_NEAR(v[0], 100.0, 10.0);
  EXPECT_LT(max_drop, 10.0);  // an instant stop would drop ~100 mm/s in one ms
  EXPECT_GT(i_stop, 100u);
}

// A parameter set the device refuses (ERROR_REPORT 12) leaves its loop off: the session fails
// with the reason, instead of streaming on to an axis the host believes closed.
TEST(VmcuLoop, RefusedLoopParametersFailTheSessionWithTheReason) {
  Rig rig;
  ASSERT_TRUE(rig.start());
  rig.configure_loop(0.3, -1.0f);  // a negative gain: the device refuses the set
  while (rig.now < 0.5 && rig.session->state() == McuState::kReady) rig.advance(rig.now + 0.001);
  EXPECT_EQ(rig.mcu->loop(0).state(), device::LoopState::kIdle);
  EXPECT_EQ(rig.mcu->status().last_error, protocol::McuError::kBadLoopConfig);
  ASSERT_EQ(rig.session->state(), McuState::kFailed);
  ASSERT_TRUE(rig.session->error().has_value());
  const std::string& m = rig.session->error()->message;
  EXPECT_NE(m.find("configuration refused"), std::string::npos) << m;
  EXPECT_NE(m.find("kp or ki negative"), std::string::npos) << m;
  EXPECT_NE(m.find("motion stopped"), std::string::npos) << m;
}

TEST(VmcuLoop, VersionOneHostStillWorks) {
  McuSessionParams sp;
  sp.protocol_version = 1;
  Rig rig({}, sp);
  ASSERT_TRUE(rig.start());
  EXPECT_EQ(rig.session->negotiated_version(), 1);
  EXPECT_EQ(rig.mcu->status().negotiated_version, 1);
  // Steps still run; a v2 message from a v1 session is refused (bad message), nothing moves oddly.
  rig.configure_loop(0.3);
  while (rig.now < rig.move.end() + 0.1) rig.advance(rig.now + 0.001);
  EXPECT_EQ(rig.session->state(), McuState::kReady);
  EXPECT_EQ(rig.mcu->loop(0).state(), device::LoopState::kIdle);
  EXPECT_EQ(rig.mcu->status().last_error, protocol::McuError::kBadMessage);
  EXPECT_NEAR(rig.axis->commanded_mm(), rig.move.d, 0.02);
}

TEST(VmcuLoop, VersionTwoHostFallsBackToAVersionOneDevice) {
  device::VirtualMcuParams mp;
  mp.protocol_version = 1;  // an old firmware: speaks only v1
  Rig rig(mp);
  ASSERT_TRUE(rig.start()) << (rig.session->error() ? rig.session->error()->message : "");
  EXPECT_EQ(rig.session->negotiated_version(), 1);
  EXPECT_EQ(rig.mcu->status().negotiated_version, 1);
  EXPECT_TRUE(rig.mcu->status().identified);
}
