// EncoderGuard: a healthy noisy stream trips nothing; a jump is judged on the samples' timestamps
// (a late sample after a move the axis can make in that time is no jump, the same distance in
// 1 ms is), an implausible sample is rejected and the fault needs three in a row; a non-finite
// reading, a stale sensor while moving and a following error each trip their fault with the
// message text; faults latch until reset().
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>

#include "config/config.hpp"
#include "control/encoder_guard.hpp"
#include "engine/control_config.hpp"

namespace fc = feedloop::control;
using fc::EncoderFault;

namespace {

// The default printer's X axis: max_velocity 300 mm/s -> 600 mm/s, margin 0.05 mm, following
// error 2 mm, 10 ms without samples while moving.
fc::EncoderGuard make_guard() {
  fc::EncoderGuard g;
  EXPECT_TRUE(g.configure(feedloop::engine::encoder_guard_params_from_config(feedloop::config::default_config(), "x")).ok());
  return g;
}

// A sample of encoder_mm taken at t_ms (the servo cycle runs at the same instant).
fc::EncoderGuardInput report(double t_ms, double encoder_mm, double reference_mm) {
  return {true, encoder_mm, t_ms * 1e-3, t_ms * 1e-3, reference_mm};
}
fc::EncoderGuardInput no_report(double t_ms, double reference_mm) { return {false, 0.0, NAN, t_ms * 1e-3, reference_mm}; }

}  // namespace

TEST(EncoderGuard, ParamsFromConfig) {
  const auto p = feedloop::engine::encoder_guard_params_from_config(feedloop::config::default_config(), "x");
  EXPECT_EQ(p.axis, "x");
  EXPECT_DOUBLE_EQ(p.max_speed_mm_s, 600.0);  // 2 x axes.x.max_velocity_mm_s
  EXPECT_DOUBLE_EQ(p.jump_margin_mm, 0.05);   // control.max_encoder_jump_mm
  EXPECT_EQ(p.reject_limit, 3);
  EXPECT_DOUBLE_EQ(p.max_following_error_mm, 2.0);
  EXPECT_DOUBLE_EQ(p.stale_s, 0.01);  // 10 periods of servo.rate_hz 1000
}

TEST(EncoderGuard, HealthyStreamTripsNothing) {
  auto g = make_guard();
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> noise(-0.01, 0.01);
  for (int k = 0; k < 10000; ++k) {
    const double ref = 150.0 * std::sin(k * 1e-3);  // up to 150 mm/s
    const bool fresh = (k % 4) != 3;                  // one sample in four missing
    ASSERT_EQ(g.update({fresh, ref - 0.3 + noise(rng), k * 1e-3, k * 1e-3, ref}), EncoderFault::none) << g.message();
    EXPECT_EQ(g.sample_accepted(), fresh);
  }
  EXPECT_STREQ(g.message(), "");
  EXPECT_EQ(g.rejected_samples(), 0);
}

// Issue 13: the servo thread woke 25 ms late and the carriage had moved 3.75 mm at 150 mm/s. A
// count of periods called that "a jump of 3.750 mm in 1 period(s)"; in 25 ms of time it is fine.
TEST(EncoderGuard, ALateSampleAfterAPossibleMoveIsNoJump) {
  auto g = make_guard();
  for (int k = 0; k <= 10; ++k) ASSERT_EQ(g.update(report(k, 0.15 * k, 0.15 * k)), EncoderFault::none);
  EXPECT_EQ(g.update(report(35.0, 0.15 * 35, 0.15 * 35)), EncoderFault::none) << g.message();
  EXPECT_TRUE(g.sample_accepted());
  EXPECT_NEAR(g.last_interval_s(), 0.025, 1e-12);
  // The same timestamps, and the most the axis can do: 600 mm/s x 25 ms + 0.05 mm.
  auto h = make_guard();
  h.update(report(10.0, 0.0, 0.0));
  EXPECT_EQ(h.update(report(35.0, 15.04, 14.0)), EncoderFault::none) << h.message();
  EXPECT_TRUE(h.sample_accepted());
}

TEST(EncoderGuard, AJumpIsRejectedAndThreeInARowTrip) {
  auto g = make_guard();
  EXPECT_EQ(g.update(report(0, 10.0, 10.0)), EncoderFault::none);
  EXPECT_EQ(g.update(report(1, 10.5, 10.0)), EncoderFault::none);  // 0.5 mm in 1 ms: 0.65 allowed
  EXPECT_TRUE(g.sample_accepted());
  // 3 mm in 1 ms: rejected (not for the loop), judged again against 10.5 at 1 ms.
  EXPECT_EQ(g.update(report(2, 13.5, 10.0)), EncoderFault::none);
  EXPECT_FALSE(g.sample_accepted());
  EXPECT_EQ(g.update(report(3, 13.5, 10.0)), EncoderFault::none);
  EXPECT_FALSE(g.sample_accepted());
  EXPECT_EQ(g.rejected_samples(), 2);
  EXPECT_EQ(g.update(report(4, 13.5, 10.0)), EncoderFault::jump);
  EXPECT_STREQ(g.message(), "x: encoder jump of 3.000 mm in 3.0 ms (limit 1.850 mm; 3 samples in a row)");
  // Latched: a good sample afterwards does not clear it.
  EXPECT_EQ(g.update(report(5, 10.5, 10.0)), EncoderFault::jump);
  g.reset();
  EXPECT_EQ(g.fault(), EncoderFault::none);
  EXPECT_EQ(g.update(report(6, 10.0, 10.0)), EncoderFault::none);
}

TEST(EncoderGuard, AGlitchOfOneSampleIsIgnored) {
  auto g = make_guard();
  g.update(report(0, 0.0, 0.0));
  EXPECT_EQ(g.update(report(1, -2.0, 0.0)), EncoderFault::none);
  EXPECT_FALSE(g.sample_accepted());
  EXPECT_EQ(g.update(report(2, 0.1, 0.1)), EncoderFault::none);  // 0.1 mm in 2 ms: fine
  EXPECT_TRUE(g.sample_accepted());
  EXPECT_EQ(g.rejected_samples(), 1);
  EXPECT_EQ(g.update(report(3, -2.0, 0.0)), EncoderFault::none);  // the count restarted
}

// The sample's own timestamp counts, not when the cycle ran: a sample taken 1 ms after the last
// one, read by a cycle 30 ms late, may differ by 0.65 mm only.
TEST(EncoderGuard, JudgesOnSampleTimesNotOnCycles) {
  auto g = make_guard();
  g.update(report(0, 0.0, 0.0));
  fc::EncoderGuardInput late{true, 2.0, 1e-3, 31e-3, 0.0};
  for (int i = 0; i < 2; ++i) EXPECT_EQ(g.update(late), EncoderFault::none);
  EXPECT_EQ(g.update(late), EncoderFault::jump);
  EXPECT_STREQ(g.message(), "x: encoder jump of 2.000 mm in 1.0 ms (limit 0.650 mm; 3 samples in a row)");
}

TEST(EncoderGuard, NonFiniteReadingTrips) {
  auto g = make_guard();
  g.update(report(0, 1.0, 1.0));
  EXPECT_EQ(g.update(report(1, std::numeric_limits<double>::quiet_NaN(), 1.0)), EncoderFault::jump);
  EXPECT_STREQ(g.message(), "x: encoder reading is not a finite number");
}

TEST(EncoderGuard, StaleWhileMovingTrips) {
  auto rest = make_guard();
  rest.update(report(0, 0.0, 0.0));
  // At rest, missing samples are fine (the MCU may report only on change).
  for (int k = 1; k <= 1000; ++k) ASSERT_EQ(rest.update(no_report(k, 0.0)), EncoderFault::none);
  auto g = make_guard();
  g.update(report(0, 0.0, 0.0));
  int tripped_at = -1;
  for (int k = 1; k <= 20 && tripped_at < 0; ++k)
    if (g.update(no_report(k, 0.05 * k)) == EncoderFault::stale) tripped_at = k;
  EXPECT_EQ(tripped_at, 11);  // 10 ms are tolerated
  EXPECT_STREQ(g.message(), "x: no encoder sample for 11.0 ms while moving (limit 10.0 ms)");
}

TEST(EncoderGuard, StaleCountsFromTheSampleNotFromItsArrival) {
  auto g = make_guard();
  // Sampled at 0 ms, read by a cycle at 9 ms: 2 ms more without one while moving is 11 ms.
  g.update({true, 0.0, 0.0, 9e-3, 0.0});
  EXPECT_EQ(g.update(no_report(10, 0.1)), EncoderFault::none);
  EXPECT_EQ(g.update(no_report(11, 0.2)), EncoderFault::stale);
}

TEST(EncoderGuard, FollowingErrorTrips) {
  auto g = make_guard();
  double enc = 0.0;
  EncoderFault f = EncoderFault::none;
  int k = 0;
  for (; k < 100 && f == EncoderFault::none; ++k) {
    enc += 0.05;                                     // the carriage lags a reference at 0.1 mm/period
    f = g.update(report(k, enc, 0.1 * (k + 1)));     // error 0.05 (k + 1)
  }
  EXPECT_EQ(f, EncoderFault::following_error);
  EXPECT_EQ(k, 41);  // first error above 2 mm: 0.05 x 41 = 2.05
  EXPECT_STREQ(g.message(), "x: following error 2.050 mm (limit 2.000 mm)");
  EXPECT_STREQ(fc::to_string(g.fault()), "following_error");
  EXPECT_FALSE(g.sample_accepted());
}

TEST(EncoderGuard, RestartForgetsTheSamplesButKeepsAFault) {
  auto g = make_guard();
  g.update(report(0, 0.0, 0.0));
  g.restart();  // motion restarts: the carriage may have been moved by hand meanwhile
  EXPECT_EQ(g.update(report(1, 5.0, 5.0)), EncoderFault::none);
  EXPECT_TRUE(g.sample_accepted());
  g.update(report(2, 5.0, 9.0));
  ASSERT_EQ(g.fault(), EncoderFault::following_error);
  g.restart();
  EXPECT_EQ(g.update(report(3, 5.0, 5.0)), EncoderFault::following_error);
}

TEST(EncoderGuard, RejectsBadParameters) {
  fc::EncoderGuard g;
  auto bad = [&](auto edit, const char* name) {
    fc::EncoderGuardParams p;
    edit(p);
    auto s = g.configure(p);
    ASSERT_FALSE(s.ok()) << name;
    EXPECT_NE(s.error().message.find(name), std::string::npos) << s.error().message;
  };
  bad([](fc::EncoderGuardParams& p) { p.max_speed_mm_s = 0.0; }, "max_speed_mm_s");
  bad([](fc::EncoderGuardParams& p) { p.jump_margin_mm = NAN; }, "jump_margin_mm");
  bad([](fc::EncoderGuardParams& p) { p.reject_limit = 0; }, "reject_limit");
  bad([](fc::EncoderGuardParams& p) { p.stale_s = -1.0; }, "stale_s");
  bad([](fc::EncoderGuardParams& p) { p.max_following_error_mm = 0.0; }, "max_following_error_mm");
  fc::EncoderGuardParams p;
  p.axis = "a_very_long_axis_name";
  ASSERT_TRUE(g.configure(p).ok());
  g.update(report(0, 0.0, 0.0));
  g.update(report(1, 0.0, 5.0));
  EXPECT_STREQ(g.message(), "a_very_: following error 5.000 mm (limit 2.000 mm)");
}
