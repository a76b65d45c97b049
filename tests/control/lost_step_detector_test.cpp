// LostStepDetector on synthetic motor / encoder traces: noise under the threshold gives no event,
// a slip of 4 full steps (with the carriage ringing into its new position) is reported once with
// its exact size, repeated slips in both directions add up, a short excursion over the threshold
// is not a slip, the settle wait is sample time, the model's expected deflection is removed, and
// bad parameters are errors.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "control/lost_step_detector.hpp"
#include "engine/control_config.hpp"

namespace fc = feedloop::control;

namespace {

constexpr double kFullStepMm = 0.2;  // 40 mm per revolution, 200 full steps: a slip cycle is 0.8 mm

fc::LostStepDetector make_detector(double full_step_mm = kFullStepMm) {
  fc::LostStepParams p;
  p.threshold_mm = 0.3;
  p.full_step_mm = full_step_mm;
  fc::LostStepDetector d;
  EXPECT_TRUE(d.configure(p).ok());
  return d;
}

struct Slip {
  int at_period;
  double size_mm;  // > 0: the rotor fell behind in +
};

struct Outcome {
  std::vector<fc::LostStepEvent> events;
  std::vector<int> event_periods;
  double max_abs_d_mm = 0.0;
};

// The motor moves at 100 mm/s. The carriage (encoder) follows the motor, minus the slips so far,
// each slip arriving with a ringing transient; reported events are recovered by shifting the
// motor command at 50 mm/s (as the PI's clamp would), and the shift is counted in the motor's
// position (steps sent).
Outcome simulate(fc::LostStepDetector& det, const std::vector<Slip>& slips, int periods, double noise_mm = 0.0,
                 unsigned seed = 1) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> noise(-noise_mm, noise_mm);
  Outcome out;
  double recovery_pending_mm = 0.0, recovered_mm = 0.0;
  for (int k = 0; k < periods; ++k) {
    const double step = std::clamp(recovery_pending_mm, -0.05, 0.05);
    recovery_pending_mm -= step;
    recovered_mm += step;
    const double motor_mm = 0.1 * k + recovered_mm;
    double lost_mm = 0.0;
    for (const Slip& s : slips) {
      if (k < s.at_period) continue;
      const double n = k - s.at_period;
      lost_mm += s.size_mm * (1.0 - std::exp(-n / 2.0) * std::cos(0.8 * n));  // rings into place
    }
    const double encoder_mm = motor_mm - lost_mm + noise(rng);
    if (auto ev = det.update(motor_mm, encoder_mm, 0.0)) {
      out.events.push_back(*ev);
      out.event_periods.push_back(k);
      recovery_pending_mm += ev->size_mm;
    }
    out.max_abs_d_mm = std::max(out.max_abs_d_mm, std::abs(det.discrepancy_mm()));
  }
  return out;
}

}  // namespace

TEST(LostStepDetector, NoiseBelowThresholdGivesNoEvent) {
  auto det = make_detector();
  const Outcome o = simulate(det, {}, 20000, 0.25);
  EXPECT_TRUE(o.events.empty());
  EXPECT_GT(o.max_abs_d_mm, 0.24);  // the noise really came close to the 0.3 mm threshold
  EXPECT_EQ(det.count(), 0);
}

TEST(LostStepDetector, SlipOfFourFullStepsReportedOnce) {
  auto det = make_detector();
  const Outcome o = simulate(det, {{1000, 4 * kFullStepMm}}, 3000, 0.05);
  ASSERT_EQ(o.events.size(), 1u);
  EXPECT_DOUBLE_EQ(o.events[0].size_mm, 0.8);
  EXPECT_EQ(o.events[0].full_steps, 4);
  EXPECT_EQ(o.events[0].count, 1);
  // Reported within the settle wait (5 periods) plus the rise to the threshold.
  EXPECT_GE(o.event_periods[0], 1000 + 5);
  EXPECT_LE(o.event_periods[0], 1000 + 8);
  EXPECT_LT(std::abs(det.discrepancy_mm()), 0.06);  // re-based: only the noise is left
}

TEST(LostStepDetector, RepeatedSlipsInBothDirections) {
  auto det = make_detector();
  const std::vector<Slip> slips = {{1000, 0.8}, {3000, 0.8}, {5000, -1.6}, {7000, 0.8}};
  const Outcome o = simulate(det, slips, 9000, 0.05, 7);
  ASSERT_EQ(o.events.size(), 4u);
  EXPECT_DOUBLE_EQ(o.events[0].size_mm, 0.8);
  EXPECT_DOUBLE_EQ(o.events[1].size_mm, 0.8);
  EXPECT_DOUBLE_EQ(o.events[2].size_mm, -1.6);  // 8 full steps at once, the other way
  EXPECT_EQ(o.events[2].full_steps, -8);
  EXPECT_DOUBLE_EQ(o.events[3].size_mm, 0.8);
  EXPECT_EQ(o.events[3].count, 4);
  EXPECT_NEAR(o.events[3].total_mm, 0.8, 1e-12);
  for (std::size_t i = 0; i < slips.size(); ++i) EXPECT_LE(o.event_periods[i], slips[i].at_period + 8);
}

TEST(LostStepDetector, ShortExcursionIsNotASlip) {
  auto det = make_detector();
  int events = 0;
  for (int k = 0; k < 100; ++k) {
    const double d = (k >= 10 && k < 14) ? 0.45 : 0.0;  // 4 periods over the threshold, then back
    if (det.update(50.0 + d, 50.0)) ++events;
    if (k == 12) {
      EXPECT_TRUE(det.pending());
    }
  }
  EXPECT_EQ(events, 0);
  EXPECT_FALSE(det.pending());
}

// The settle wait is sample time (settle_periods x period_s), not a count of updates: a late
// update 20 ms after the last one does not confirm a slip that crossed the threshold just before
// it, nor does it take the wait five times over.
TEST(LostStepDetector, SettleWaitIsCountedInSampleTime) {
  auto det = make_detector();  // settle 5 x 1 ms
  EXPECT_FALSE(det.update(50.8, 50.0, 0.0, 1e-3));   // crosses: the wait starts here
  EXPECT_TRUE(det.pending());
  EXPECT_FALSE(det.update(50.8, 50.0, 0.0, 4e-3));   // 4 ms beyond
  auto ev = det.update(50.8, 50.0, 0.0, 1e-3);       // 5 ms: confirmed
  ASSERT_TRUE(ev.has_value());
  EXPECT_DOUBLE_EQ(ev->size_mm, 0.8);
  // One late update (20 ms) after the crossing confirms at once, as 20 on-time ones would.
  auto late = make_detector();
  EXPECT_FALSE(late.update(50.8, 50.0, 0.0, 1e-3));
  EXPECT_TRUE(late.update(50.8, 50.0, 0.0, 20e-3).has_value());
  // Without dt_s each update is one period_s: the sixth confirms.
  auto counted = make_detector();
  int confirmed_at = -1;
  for (int k = 0; k < 10 && confirmed_at < 0; ++k)
    if (counted.update(50.8, 50.0)) confirmed_at = k;
  EXPECT_EQ(confirmed_at, 5);
  fc::LostStepParams bad;
  bad.period_s = 0.0;
  EXPECT_FALSE(fc::LostStepDetector().configure(bad).ok());
}

TEST(LostStepDetector, ExpectedDeflectionIsRemoved) {
  // 0.7 mm of belt stretch the model predicts: with the model no event; without it, rounding to
  // whole cycles turns it (0.875 of a cycle) into a false slip of 0.8 mm.
  auto with_model = make_detector();
  auto without_model = make_detector();
  int events_with = 0, events_without = 0;
  for (int k = 0; k < 200; ++k) {
    const double motor = 0.1 * k, encoder = motor - 0.7;
    if (with_model.update(motor, encoder, 0.7)) ++events_with;
    if (without_model.update(motor, encoder)) ++events_without;
  }
  EXPECT_EQ(events_with, 0);
  EXPECT_EQ(events_without, 1);
  EXPECT_DOUBLE_EQ(without_model.total_mm(), 0.8);
}

// A settled d that is not near a whole cycle (0.5 mm of a 0.8 mm cycle: more than
// kSlipCycleTolerance from one) is a model's error, not the rotor in another equilibrium: no
// event, however long it stays; when it then moves to a whole cycle, the slip is found.
TEST(LostStepDetector, ASlipIsNearAWholeCycle) {
  EXPECT_DOUBLE_EQ(fc::kSlipCycleTolerance, 0.25);
  auto det = make_detector();
  int events = 0;
  for (int k = 0; k < 400; ++k) events += det.update(0.1 * k, 0.1 * k - 0.5) ? 1 : 0;
  EXPECT_EQ(events, 0);
  for (int k = 400; k < 420; ++k) events += det.update(0.1 * k, 0.1 * k - 0.78) ? 1 : 0;
  EXPECT_EQ(events, 1);
  EXPECT_DOUBLE_EQ(det.total_mm(), 0.8);
}

TEST(LostStepDetector, UnknownStepSizeReportsTheMeasuredOffset) {
  auto det = make_detector(0.0);
  const Outcome o = simulate(det, {{500, 0.37}}, 1500);
  ASSERT_EQ(o.events.size(), 1u);
  EXPECT_EQ(o.events[0].full_steps, 0);
  // The value 6 periods after the slip, while it still rings: exp(-3) cos(4.8) = 0.0044 of it.
  EXPECT_NEAR(o.events[0].size_mm, 0.37, 0.01);
}

TEST(LostStepDetector, RejectsBadParameters) {
  fc::LostStepDetector det;
  fc::LostStepParams p;
  p.threshold_mm = 0.0;
  EXPECT_FALSE(det.configure(p).ok());
  p = fc::LostStepParams{};
  p.full_step_mm = 0.05;  // cycle 0.2 mm < 2 x 0.3 mm: a half-cycle residual would re-trigger
  auto s = det.configure(p);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("threshold"), std::string::npos);
  p = fc::LostStepParams{};
  p.settle_periods = 0;
  EXPECT_FALSE(det.configure(p).ok());
  feedloop::config::ControlConfig c;
  c.skipped_step_threshold_mm = 0.25;
  const fc::LostStepParams q = feedloop::engine::lost_step_params_from_config(c, 0.2);
  EXPECT_EQ(q.threshold_mm, 0.25);
  EXPECT_EQ(q.full_step_mm, 0.2);
}
