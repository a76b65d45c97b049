// The device loop (drivers/device/axis_loop.hpp) on a small spring-mass plant with Coulomb
// friction its model lacks (axis_loop_rig.hpp): convergence at 1 and 10 kHz, following-error
// trip, skipped-step detection and recovery, encoder plausibility on timestamps (a glitch is
// rejected, a legitimate move after a long gap between samples is not), the watchdog's controlled
// stop, the bumpless gain change at a stated MCU time, and no allocation.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <new>
#include <utility>

#include "axis_loop_rig.hpp"
#include "drivers/device/loop_pi.hpp"
#include "drivers/device/slip_detector.hpp"

using feedloop::device::AxisLoop;
using feedloop::device::LoopEvent;
using feedloop::device::LoopEventKind;
using feedloop::device::LoopParamError;
using feedloop::device::LoopParams;
using feedloop::device::LoopPi;
using feedloop::device::LoopState;
using feedloop::device::StopReason;
using feedloop::testing::LoopRig;
using feedloop::testing::RigParams;

namespace {

// Allocation counter, armed only around the code under test.
std::atomic<bool> g_armed{false};
std::atomic<long> g_allocs{0};

}  // namespace

void* operator new(std::size_t n) {
  if (g_armed.load(std::memory_order_relaxed)) g_allocs.fetch_add(1, std::memory_order_relaxed);
  void* p = std::malloc(n ? n : 1);
  if (!p) throw std::bad_alloc();
  return p;
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace {

// Mean |e| (mm) over [t0, t1] sampled at every tick.
double mean_abs_error_mm(const LoopRig& rig, double t0, double t1) {
  double s = 0;
  int n = 0;
  for (const auto& u : rig.u_log())
    if (u.t >= t0 && u.t <= t1) {
      s += std::abs(u.e_nm) * 1e-6;
      ++n;
    }
  return n ? s / n : 1e9;
}

struct Convergence {
  double hold_error_mm;     // |r - x| averaged over the last 100 ms of the hold (ground truth)
  double cruise_error_mm;   // mean |e| over the cruise
};

Convergence run_move(double control_hz, bool loop_on) {
  RigParams p;
  p.control_hz = control_hz;
  p.loop_enabled = loop_on;
  LoopRig rig(p);
  const double t_end = rig.move_end_s() + 0.4;
  rig.start(0.0, t_end + 1.0);
  rig.run_until(rig.move_end_s() + 0.3);
  double s = 0;
  int n = 0;
  while (rig.t() < t_end) {
    rig.run_until(rig.t() + 0.001);
    s += std::abs(rig.error_mm(rig.t()));
    ++n;
  }
  const double ta = p.speed_mm_s / p.accel_mm_s2;
  return {s / n, mean_abs_error_mm(rig, p.start_s + ta + 0.02, rig.move_end_s() - ta)};
}

}  // namespace

class AxisLoopRate : public ::testing::TestWithParam<double> {};

TEST_P(AxisLoopRate, ConvergesDespiteUnmodelledFriction) {
  const double hz = GetParam();
  const Convergence open = run_move(hz, false);
  const Convergence closed = run_move(hz, true);
  std::printf("%.0f Hz: hold |e| open %.6f mm closed %.6f mm; cruise |e| open %.6f closed %.6f\n", hz,
              open.hold_error_mm, closed.hold_error_mm, open.cruise_error_mm, closed.cruise_error_mm);
  // Friction 4 N on a 110 kN/m belt: the open loop sticks up to 36 um off; closed, the integral
  // takes the carriage to within a fraction of the 5 um microstep.
  EXPECT_GT(open.hold_error_mm, 0.010);
  EXPECT_LT(closed.hold_error_mm, 0.004);
  EXPECT_LT(closed.hold_error_mm, 0.25 * open.hold_error_mm);
  EXPECT_LT(closed.cruise_error_mm, 0.5 * open.cruise_error_mm);
}

INSTANTIATE_TEST_SUITE_P(Rates, AxisLoopRate, ::testing::Values(1000.0, 10000.0));

// The sub-step trim (LoopParams::sub_step_trim, MotorPort::set_step_fraction): the correction below
// one microstep goes to the driver's current phase, so at rest the carriage is held within about
// an encoder count of r instead of within the microstep's rounding. Measured at rest after the
// move (the last 100 ms of a 0.6 s hold), with and without, friction as given: the encoder's
// reading against r in counts (what "returns within one count" is judged on), and the truth.
struct Hold {
  double worst_reading_counts, worst_truth_um;
};
Hold hold_error(bool trim, double friction_n) {
  RigParams p;
  p.friction_n = friction_n;
  LoopRig rig(p);
  rig.params().sub_step_trim = trim;
  rig.start(0.0, rig.move_end_s() + 2.0);
  rig.run_until(rig.move_end_s() + 0.5);
  const double t0 = rig.t();
  double worst = 0.0;
  while (rig.t() < rig.move_end_s() + 0.6) {
    rig.run_until(rig.t() + 0.001);
    worst = std::max(worst, std::abs(rig.error_mm(rig.t())) * 1e3);
  }
  double worst_e = 0.0;
  for (const auto& u : rig.u_log())
    if (u.t >= t0) worst_e = std::max(worst_e, static_cast<double>(std::abs(u.e_nm)));
  return {worst_e / p.count_nm, worst};
}

TEST(AxisLoop, TheSubStepTrimHoldsTheCarriageWithinACount) {
  for (double friction : {0.0, 0.5}) {
    const Hold without = hold_error(false, friction), with = hold_error(true, friction);
    std::printf(
        "friction %.1f N, at rest: the encoder against r: worst %.2f counts in whole steps (5 um), "
        "%.2f counts with the trim; the carriage's truth %.3f / %.3f um\n",
        friction, without.worst_reading_counts, with.worst_reading_counts, without.worst_truth_um,
        with.worst_truth_um);
    // The reading stays within one count of r (the integral holds inside a count); the truth
    // within two (the reading's floor plus that count).
    EXPECT_LT(with.worst_reading_counts, 1.0) << friction;
    EXPECT_LT(with.worst_truth_um, 2.0 * 0.49) << friction;
    if (friction == 0.0) {
      EXPECT_GT(without.worst_reading_counts, 2.0);  // whole steps: up to half a 5 um step
    }
  }
}

// The proportional band (AxisLoop::kProportionalBandCounts with the trim): P acts on the error
// beyond the band only, the integral on all of it; a gain change stays bumpless.
TEST(LoopPi, TheProportionalTermActsOnTheErrorBeyondItsBand) {
  LoopPi pi;
  pi.configure(0.5f, 20.0f, 1.0e6f);
  EXPECT_FLOAT_EQ(pi.update(1000.0f, 1e-4f, false, 1470.0f), 0.0f);    // inside: nothing
  EXPECT_FLOAT_EQ(pi.update(2000.0f, 1e-4f, false, 1470.0f), 265.0f);  // 0.5 x (2000 - 1470)
  EXPECT_FLOAT_EQ(pi.update(-2000.0f, 1e-4f, false, 1470.0f), -265.0f);
  EXPECT_FLOAT_EQ(pi.update(2000.0f, 1e-4f, false, 0.0f), 1000.0f);  // no band: all of it
  EXPECT_FLOAT_EQ(pi.update(2000.0f, 0.1f, true, 1470.0f), 265.0f + 20.0f * 2000.0f * 0.1f);
  const float before = pi.output_nm();
  pi.set_gains(1.0f, 20.0f, 1.0e6f);
  EXPECT_FLOAT_EQ(pi.update(2000.0f, 1e-4f, false, 1470.0f), before);
}

TEST(AxisLoop, FollowingErrorTripsIntoAControlledStop) {
  RigParams p;
  LoopRig rig(p);
  rig.params().max_following_error_nm = 1.0e6f;  // 1 mm
  rig.start(0.0, 1.0);
  rig.run_until(0.06);
  EXPECT_EQ(rig.count(LoopEventKind::kFollowingError), 0);
  rig.block_carriage(true);  // a crash: the carriage stops dead, the motor keeps going
  rig.run_until(0.2);
  ASSERT_EQ(rig.count(LoopEventKind::kFollowingError), 1);
  EXPECT_EQ(rig.count(LoopEventKind::kStopStarted), 1);
  EXPECT_EQ(rig.count(LoopEventKind::kStopDone), 1);
  EXPECT_EQ(rig.loop().stop_reason(), StopReason::kFollowingError);
  EXPECT_EQ(rig.loop().state(), LoopState::kStopped);
  for (const LoopEvent& e : rig.events())
    if (e.kind == LoopEventKind::kFollowingError) {
      EXPECT_GT(e.a, 1000000);
      EXPECT_EQ(e.b, 1000000);
      // The trip came when |e| first exceeded 1 mm: the carriage was blocked at 60 ms, r moves at
      // <= 100 mm/s, so 1 mm of error takes >= 10 ms (minus the belt's stretch).
      EXPECT_GT(e.clock, rig.clock_at(0.065));
      EXPECT_LT(e.clock, rig.clock_at(0.085));
    }
}

TEST(AxisLoop, SkippedStepIsDetectedOnceAndRecovered) {
  RigParams p;
  LoopRig rig(p);
  rig.start(0.0, 1.0);
  const double t_slip = rig.move_end_s() - 0.05;  // in the cruise
  rig.run_until(t_slip);
  EXPECT_EQ(rig.count(LoopEventKind::kSlip), 0);
  rig.lose_cycle(+1);  // the rotor falls back 4 full steps (0.32 mm) behind the field
  rig.run_until(t_slip + 0.004);
  const double err_after_slip = std::abs(rig.error_mm(rig.t()));
  rig.run_until(rig.move_end_s() + 0.3);
  ASSERT_EQ(rig.count(LoopEventKind::kSlip), 1);
  for (const LoopEvent& e : rig.events())
    if (e.kind == LoopEventKind::kSlip) {
      EXPECT_EQ(e.a, 1);  // one cycle, in +: the motor must make up 64 microsteps
      EXPECT_NEAR(static_cast<double>(e.b), 4.0 * 16.0 * p.step_nm, 1.0);
      EXPECT_LT(e.clock, rig.clock_at(t_slip + 0.02));  // confirmed within 5 settle ticks + ringing
    }
  const double err_end = std::abs(rig.error_mm(rig.t()));
  std::printf("error just after the slip %.3f mm, 300 ms after the move %.4f mm, device steps %lld\n",
              err_after_slip, err_end, static_cast<long long>(rig.device_steps()));
  EXPECT_GT(err_after_slip, 0.2);
  EXPECT_LT(err_end, 0.005);  // re-synchronised: back to within a microstep
  EXPECT_EQ(rig.loop().state(), LoopState::kRunning);
}

// Behind a model inverse the host's steps lead r by what the better model knows (here a 20 N
// friction: 0.18 mm of belt stretch, more than the 120 um slip threshold, that the loop's own
// deflection terms lack). Checked against the host's steps' lead there is no false slip, and a
// real one is still found once. Against the loop's own model the stretch is no slip either since
// a slip must be near a whole cycle (kSlipCycleTolerance): it was one false slip before.
TEST(AxisLoop, BehindAModelInverseItsLeadIsNoSlip) {
  for (bool from_host_steps : {false, true}) {
    RigParams p;
    p.friction_n = 20.0;
    p.inverse_feedforward = true;
    LoopRig rig(p);
    rig.params().deflection_from_host_steps = from_host_steps;
    rig.start(0.0, 1.0);
    const double t_slip = rig.move_end_s() - 0.05;
    rig.run_until(t_slip);
    const int false_slips = rig.count(LoopEventKind::kSlip);
    rig.lose_cycle(+1);
    rig.run_until(rig.move_end_s() + 0.3);
    const int slips = rig.count(LoopEventKind::kSlip) - false_slips;
    std::printf("deflection from %s: %d false slips, the real one found %d time(s), final error %.4f mm\n",
                from_host_steps ? "the host's steps" : "the loop's model", false_slips, slips,
                rig.error_mm(rig.t()));
    EXPECT_EQ(false_slips, 0);
    EXPECT_EQ(slips, 1);
    EXPECT_LT(std::abs(rig.error_mm(rig.t())), from_host_steps ? 0.005 : 0.03);
  }
}

// The detector itself: d held beyond the threshold at 0.45 of a torque-law cycle (a model's
// error) is watched and never confirmed; at 0.8 and at 1.1 cycles (a slip beside a transient) it
// is confirmed as one whole cycle once settled; d that moves from 0.45 to a whole cycle (the
// transient passing) is confirmed then.
TEST(SlipDetector, ASlipIsAWholeTorqueLawCycle) {
  using feedloop::device::kSlipCycleTolerance;
  using feedloop::device::SlipDetector;
  constexpr float kCycleNm = 678600.0f, kThresholdNm = 300000.0f, kDtS = 1e-4f;
  EXPECT_FLOAT_EQ(kSlipCycleTolerance, 0.25f);
  const auto held = [&](float cycles, int ticks) {
    SlipDetector d;
    d.configure(kThresholdNm, kCycleNm, 0.03f, 0.0f);
    int events = 0;
    float size_nm = 0.0f;
    for (int k = 0; k < ticks; ++k) {
      const auto ev = d.update(cycles * kCycleNm, 0.0f, kDtS);
      if (ev.happened) {
        ++events;
        size_nm = ev.size_nm;
      }
    }
    return std::make_pair(events, size_nm);
  };
  EXPECT_EQ(held(0.45f, 20000).first, 0);
  EXPECT_EQ(held(-0.45f, 20000).first, 0);
  for (float c : {0.8f, 1.1f, -1.0f}) {
    const auto [events, size_nm] = held(c, 20000);
    EXPECT_EQ(events, 1) << c;
    EXPECT_FLOAT_EQ(size_nm, (c > 0.0f ? 1.0f : -1.0f) * kCycleNm) << c;
  }
  SlipDetector d;
  d.configure(kThresholdNm, kCycleNm, 0.03f, 0.0f);
  int events = 0;
  for (int k = 0; k < 2000; ++k) events += d.update(0.45f * kCycleNm, 0.0f, kDtS).happened;
  EXPECT_EQ(events, 0);
  EXPECT_TRUE(d.pending());
  int at = -1;
  for (int k = 0; k < 2000 && at < 0; ++k)
    if (d.update(0.95f * kCycleNm, 0.0f, kDtS).happened) at = k;
  EXPECT_EQ(at, 0);  // settled long ago: confirmed on the first sample near a whole cycle
  EXPECT_EQ(d.count(), 1u);
}

// A lag the model lacks (docs/decisions.md, "A lag the model lacks is no slip"): d = tau v from
// an encoder that reports tau = 8 ms late, on moves of 6000 mm/s^2 to +-150 mm/s and back, is no
// slip (without the learned lag it is beyond the 0.3 mm threshold from 36 mm/s on and at 150 mm/s
// 1.2 mm, 1.86 cycles: a whole cycle's neighbour); tau is learned within 5 %. A whole cycle lost
// in a later cruise is still confirmed once, and the lag learned stays within 5 % through it.
TEST(SlipDetector, ALagTheModelLacksIsNoSlip) {
  using feedloop::device::SlipDetector;
  constexpr float kCycleNm = 678600.0f, kThresholdNm = 300000.0f, kDtS = 1e-3f, kLagS = 0.008f;
  constexpr float kAccelNmS2 = 6000e6f, kSpeedNmS = 150e6f;
  // A trapezoid of 0.1 s: ramp 25 ms, cruise, ramp down; direction alternating per move.
  const auto speed_at = [&](float t_s, int move) {
    const float ta = kSpeedNmS / kAccelNmS2, t_move = 0.1f;
    const float v =
        t_s < ta ? kAccelNmS2 * t_s : (t_s > t_move - ta ? kAccelNmS2 * (t_move - t_s) : kSpeedNmS);
    return (move % 2 == 0 ? 1.0f : -1.0f) * (v > 0.0f ? v : 0.0f);
  };
  for (bool slip : {false, true}) {
    SlipDetector d;
    d.configure(kThresholdNm, kCycleNm, 0.03f);
    int events = 0, first_event_move = -1;
    float slip_nm = 0.0f, lag_before_slip_s = 0.0f;
    for (int move = 0; move < 20; ++move)
      for (int k = 0; k < 120; ++k) {  // 100 ms moving, 20 ms at rest
        const float t = static_cast<float>(k) * kDtS, v = speed_at(t, move);
        if (slip && move == 12 && k == 50) {
          lag_before_slip_s = d.learned_lag_s();
          slip_nm = kCycleNm;  // the rotor falls one cycle behind in the cruise
        }
        if (d.update(kLagS * v + slip_nm, 0.0f, kDtS, v).happened && ++events == 1)
          first_event_move = move;
      }
    std::printf(
        "%s: %d slip(s) confirmed (first in move %d), lag learned %.3f ms (%.3f before the slip)\n",
        slip ? "a cycle lost in move 12" : "lag alone", events, first_event_move,
        d.learned_lag_s() * 1e3, lag_before_slip_s * 1e3);
    EXPECT_EQ(events, slip ? 1 : 0);
    if (slip) {
      EXPECT_EQ(first_event_move, 12);
      EXPECT_NEAR(lag_before_slip_s, kLagS, 0.05f * kLagS);
    }
    EXPECT_NEAR(d.learned_lag_s(), kLagS, 0.05f * kLagS);
    if (!slip) {  // a speed that is not one (NaN, infinite) teaches nothing and confirms nothing
      const float lag_s = d.learned_lag_s();
      int bad_events = 0;
      for (float v : {std::nanf(""), INFINITY, -INFINITY})
        for (int k = 0; k < 100; ++k) bad_events += d.update(0.0f, 0.0f, kDtS, v).happened;
      EXPECT_EQ(bad_events, 0);
      EXPECT_NEAR(d.learned_lag_s(), lag_s, 0.01f * lag_s);  // as if at rest
    }
  }
}

TEST(AxisLoop, EncoderGlitchIsRejectedWithoutTrip) {
  RigParams p;
  LoopRig rig(p);
  rig.start(0.0, 1.0);
  rig.run_until(0.08);
  const float u_before = rig.loop().pi().output_nm();
  rig.run_until(0.0805);
  rig.set_glitch_mm(2.0);  // one sample 2 mm off: the axis cannot move that far in 1 ms at 500 mm/s
  rig.run_until(0.0815);
  rig.set_glitch_mm(0.0);
  const float u_after = rig.loop().pi().output_nm();
  rig.run_until(0.1);
  EXPECT_EQ(rig.count(LoopEventKind::kEncoderReject), 1);
  EXPECT_EQ(rig.count(LoopEventKind::kEncoderFault), 0);
  EXPECT_EQ(rig.loop().state(), LoopState::kRunning);
  EXPECT_EQ(rig.loop().encoder_rejects(), 1u);
  // The correction did not chase the glitch (a 2 mm error x K_P would be 1 mm).
  EXPECT_LT(std::abs(u_after - u_before), 20000.0f);
}

TEST(AxisLoop, PersistentEncoderFaultTrips) {
  RigParams p;
  LoopRig rig(p);
  rig.start(0.0, 1.0);
  rig.run_until(0.08);
  rig.set_glitch_mm(5.0);  // the encoder's reading is off for good
  rig.run_until(0.2);
  EXPECT_EQ(rig.count(LoopEventKind::kEncoderReject), 2);  // reject_limit 3: two rejects, then the fault
  EXPECT_EQ(rig.count(LoopEventKind::kEncoderFault), 1);
  EXPECT_EQ(rig.loop().stop_reason(), StopReason::kEncoderFault);
  EXPECT_EQ(rig.loop().state(), LoopState::kStopped);
}

TEST(AxisLoop, LegitimateMoveAfterALongGapIsNotAJump) {
  // control/encoder_guard.cpp counted periods: a 50 ms gap at 100 mm/s (5 mm) looked like a jump
  // of 5 mm in "1 period". Here plausibility is judged on the samples' MCU timestamps.
  RigParams p;
  p.distance_mm = 40.0;
  LoopRig rig(p);
  rig.params().max_speed_nm_s = 150.0e6f;  // 150 mm/s: 5 mm in 50 ms is fine, 5 mm in 1 ms is not
  rig.start(0.0, 1.0);
  const double t_gap = p.start_s + 0.1;  // cruising at 100 mm/s
  rig.run_until(t_gap);
  const uint64_t ticks_before = rig.loop().ticks();
  rig.skip_ticks(t_gap - 0.0005, t_gap + 0.0495);  // the ticks at t_gap .. t_gap + 49 ms
  rig.run_until(t_gap + 0.0595);
  EXPECT_EQ(rig.count(LoopEventKind::kEncoderReject), 0);
  EXPECT_EQ(rig.count(LoopEventKind::kEncoderFault), 0);
  EXPECT_EQ(rig.loop().deadline_misses(), 1u);  // the tick after the gap was late
  // The MCU free again at +49.5 ms runs the late tick at once, then 10 on the grid.
  EXPECT_EQ(rig.loop().ticks() - ticks_before, 11u);
  EXPECT_EQ(rig.loop().state(), LoopState::kRunning);
  rig.run_until(rig.move_end_s() + 0.3);
  EXPECT_LT(std::abs(rig.error_mm(rig.t())), 0.004);
}

TEST(AxisLoop, HostSilentStopDecelerates) {
  RigParams p;
  p.distance_mm = 60.0;
  LoopRig rig(p);
  rig.params().stop_decel_nm_s2 = 2.0e9f;  // 2000 mm/s^2
  rig.start(0.0, 1.0);
  const double t_stop = p.start_s + 0.2;  // cruising at 100 mm/s
  rig.run_until(t_stop);
  rig.loop().request_stop(StopReason::kHostSilent);
  const size_t i0 = rig.motor_log().size();
  rig.run_until(t_stop + 0.15);
  ASSERT_EQ(rig.count(LoopEventKind::kStopDone), 1);
  EXPECT_EQ(rig.loop().stop_reason(), StopReason::kHostSilent);
  // Motor speed over 2 ms windows: from ~100 mm/s to 0 in ~50 ms, never faster than the ramp.
  const auto& m = rig.motor_log();
  const size_t w = 400;  // 2 ms of 5 us steps
  double v_prev = (m[i0] - m[i0 - w]) / 0.002;
  double max_decel = 0, v_first = v_prev;
  for (size_t i = i0 + w; i < m.size(); i += w) {
    const double v = (m[i] - m[i - w]) / 0.002;
    max_decel = std::max(max_decel, (v_prev - v) / 0.002);
    v_prev = v;
  }
  const double travel = m.back() - m[i0];
  std::printf("stop: v0 %.1f mm/s, max decel over 2 ms %.0f mm/s^2, travel %.3f mm, stopped after %.1f ms\n",
              v_first, max_decel, travel, (rig.stopped_at_s() - t_stop) * 1e3);
  EXPECT_NEAR(v_first, 100.0, 5.0);
  EXPECT_LT(max_decel, 2000.0 * 1.3);  // the ramp, give or take a microstep per window
  EXPECT_NEAR(travel, 100.0 * 100.0 / (2 * 2000.0), 0.1);  // v0^2 / 2a = 2.5 mm
  EXPECT_NEAR(rig.stopped_at_s() - t_stop, 0.05, 0.005);
  EXPECT_NEAR(v_prev, 0.0, 1e-9);
}

TEST(AxisLoop, TargetHorizonStopsBeforeTheQueueRunsOut) {
  RigParams p;
  p.distance_mm = 60.0;
  LoopRig rig(p);
  rig.params().stop_decel_nm_s2 = 3.0e9f;
  rig.params().horizon_margin_ticks = static_cast<uint32_t>(0.02 * p.clock_hz);  // 20 ms
  const double t_last_knot = p.start_s + 0.2;
  rig.start(0.0, t_last_knot);  // the host goes silent after this knot, mid-cruise
  rig.run_until(t_last_knot + 0.2);
  ASSERT_EQ(rig.count(LoopEventKind::kStopStarted), 1);
  double motor_at_start_mm = 0;
  for (const LoopEvent& e : rig.events())
    if (e.kind == LoopEventKind::kStopStarted) {
      motor_at_start_mm = rig.motor_log()[static_cast<size_t>(std::llround(e.clock / (p.clock_hz * p.h_s))) - 1];
      EXPECT_EQ(e.a, static_cast<int64_t>(StopReason::kTargetHorizon));
      EXPECT_EQ(e.clock, rig.clock_at(t_last_knot) - 19 * 20000);  // the first tick < 20 ms before the end
      EXPECT_NEAR(static_cast<double>(e.b), 100.0e6, 1.0e6);  // braking from r's 100 mm/s
    }
  EXPECT_EQ(rig.loop().state(), LoopState::kStopped);
  // v0^2 / 2a = 1.67 mm of braking from where the motor was at the stop's start.
  EXPECT_NEAR(rig.motor_mm() - motor_at_start_mm, 100.0 * 100.0 / 6000.0, 0.02);
}

TEST(AxisLoop, GainChangeAtAStatedClockIsBumpless) {
  RigParams p;
  LoopRig rig(p);
  rig.start(0.0, 1.0);
  const double t_change = p.start_s + 0.09;  // cruising, with a friction lag in e
  rig.run_until(t_change - 0.0005);
  LoopParams q = rig.params();
  q.kp = 2.0f;
  q.ki_per_s = 80.0f;
  ASSERT_EQ(rig.loop().stage(q, rig.clock_at(t_change)), LoopParamError::kOk);
  rig.run_until(t_change + 0.01);
  int activations = 0;
  for (const LoopEvent& e : rig.events())
    if (e.kind == LoopEventKind::kActivated) {
      ++activations;
      if (activations == 2) {
        EXPECT_EQ(e.clock, rig.clock_at(t_change));  // exactly on the stated clock
      }
    }
  EXPECT_EQ(activations, 2);
  EXPECT_FLOAT_EQ(rig.loop().pi().kp(), 2.0f);
  // u across the change: the jump is what one tick of the old law would give, not (K_P' - K_P) e.
  const auto& log = rig.u_log();
  size_t k = 0;
  while (log[k].t < t_change - 1e-9) ++k;
  const double du = std::abs(log[k].u_nm - log[k - 1].u_nm);
  const double du_prev = std::abs(log[k - 1].u_nm - log[k - 2].u_nm);
  const double bump = std::abs((2.0 - 0.5) * log[k - 1].e_nm);
  std::printf("gain change: e %.0f nm, du at the change %.1f nm, du the tick before %.1f nm, unbumpless jump %.0f nm\n",
              log[k - 1].e_nm, du, du_prev, bump);
  EXPECT_GT(bump, 1000.0);
  EXPECT_LT(du, 0.2 * bump);
}

TEST(AxisLoop, BadParametersAreRejectedWithTheirGroup) {
  AxisLoop loop;
  loop.init(20e6f);
  LoopParams p;
  p.enabled = true;
  p.period_ticks = 20000;
  p.nm_per_count_q16 = 490 << 16;
  p.nm_per_step_q16 = 0;
  EXPECT_EQ(loop.stage(p, 0), LoopParamError::kGeometry);
  p.nm_per_step_q16 = 5000 << 16;
  p.kp = -1.0f;
  EXPECT_EQ(loop.stage(p, 0), LoopParamError::kGains);
  p.kp = 0.5f;
  p.slip_cycle_nm = 400e3f;  // not > 2 x 250 um
  EXPECT_EQ(loop.stage(p, 0), LoopParamError::kSlip);
  p.slip_cycle_nm = 0.0f;
  EXPECT_EQ(loop.stage(p, 0), LoopParamError::kOk);
  LoopEvent e;
  int rejected = 0;
  while (loop.pop_event(e)) rejected += e.kind == LoopEventKind::kRejectedParams;
  EXPECT_EQ(rejected, 3);
  EXPECT_EQ(loop.next_tick_clock(), 0);
}

TEST(AxisLoop, TicksAllocateNothing) {
  AxisLoop loop;
  loop.init(20e6f);
  LoopParams p;
  p.enabled = true;
  p.period_ticks = 2000;  // 10 kHz
  p.nm_per_count_q16 = 490u << 16;
  p.nm_per_step_q16 = 5000u << 16;
  p.slip_cycle_nm = 320e3f;
  p.slip_threshold_nm = 120e3f;
  g_allocs = 0;
  g_armed = true;
  loop.stage(p, 0);
  int64_t steps = 0, dev = 0;
  for (int k = 0; k < 100000; ++k) {
    const int64_t clock = static_cast<int64_t>(k) * 2000;
    if (k % 10 == 0) loop.push_target({clock + 2000000, (clock + 2000000) / 400});
    feedloop::device::LoopTickIn in{clock, clock / 400 / 490, steps, dev};
    feedloop::device::LoopTickOut out;
    loop.tick(in, out);
    dev += out.extra_steps;
    steps = clock / 400 / 5000 + dev;
    LoopEvent e;
    while (loop.pop_event(e)) {
    }
  }
  g_armed = false;
  EXPECT_EQ(g_allocs.load(), 0);
  EXPECT_EQ(loop.ticks(), 100000u);
}
