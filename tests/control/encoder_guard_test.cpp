// EncoderGuard: a healthy noisy stream trips nothing; a jump, a non-finite reading, a stale
// sensor while moving and a following error each trip their fault with the message text; the
// jump limit scales with the periods since the last report; faults latch until reset().
#include <gtest/gtest.h>

#include <limits>
#include <random>
#include <string>

#include "control/encoder_guard.hpp"
#include "engine/control_config.hpp"

namespace fc = feedloop::control;
using fc::EncoderFault;

namespace {

fc::EncoderGuard make_guard() {
  feedloop::config::ControlConfig c;  // jump 1 mm, following error 2 mm
  fc::EncoderGuard g;
  EXPECT_TRUE(g.configure(feedloop::engine::encoder_guard_params_from_config(c, "x")).ok());
  return g;
}

fc::EncoderGuardInput report(double encoder_mm, double reference_mm) { return {true, encoder_mm, reference_mm}; }
fc::EncoderGuardInput no_report(double reference_mm) { return {false, 0.0, reference_mm}; }

}  // namespace

TEST(EncoderGuard, HealthyStreamTripsNothing) {
  auto g = make_guard();
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> noise(-0.01, 0.01);
  for (int k = 0; k < 10000; ++k) {
    const double ref = 150.0 * std::sin(k * 1e-3);                   // up to 150 mm/s
    const bool fresh = (k % 4) != 3;                                   // one report in four missing
    ASSERT_EQ(g.update({fresh, ref - 0.3 + noise(rng), ref}), EncoderFault::none) << g.message();
  }
  EXPECT_STREQ(g.message(), "");
}

TEST(EncoderGuard, JumpTrips) {
  auto g = make_guard();
  EXPECT_EQ(g.update(report(10.0, 10.0)), EncoderFault::none);
  EXPECT_EQ(g.update(report(10.5, 10.0)), EncoderFault::none);
  EXPECT_EQ(g.update(report(13.5, 10.0)), EncoderFault::jump);
  EXPECT_STREQ(g.message(), "x: encoder jump of 3.000 mm in 1 period(s) (limit 1.000 mm)");
  // Latched: a good report afterwards does not clear it.
  EXPECT_EQ(g.update(report(10.0, 10.0)), EncoderFault::jump);
  g.reset();
  EXPECT_EQ(g.fault(), EncoderFault::none);
  EXPECT_EQ(g.update(report(10.0, 10.0)), EncoderFault::none);
}

TEST(EncoderGuard, JumpLimitScalesWithMissingReports) {
  auto g = make_guard();
  g.update(report(0.0, 0.0));
  g.update(no_report(0.0));
  g.update(no_report(0.0));
  EXPECT_EQ(g.periods_since_report(), 2);
  EXPECT_EQ(g.update(report(2.9, 1.0)), EncoderFault::none);  // 3 periods: up to 3 mm
  g.update(no_report(1.0));
  EXPECT_EQ(g.update(report(-0.2, 1.0)), EncoderFault::jump);  // 2 periods: 3.1 mm > 2 mm
  EXPECT_STREQ(g.message(), "x: encoder jump of -3.100 mm in 2 period(s) (limit 2.000 mm)");
}

TEST(EncoderGuard, NonFiniteReadingTrips) {
  auto g = make_guard();
  g.update(report(1.0, 1.0));
  EXPECT_EQ(g.update(report(std::numeric_limits<double>::quiet_NaN(), 1.0)), EncoderFault::jump);
  EXPECT_STREQ(g.message(), "x: encoder reading is not a finite number");
}

TEST(EncoderGuard, StaleWhileMovingTrips) {
  auto g = make_guard();
  g.update(report(0.0, 0.0));
  // At rest, missing reports are fine (the MCU may report only on change).
  for (int k = 0; k < 1000; ++k) ASSERT_EQ(g.update(no_report(0.0)), EncoderFault::none);
  g.update(report(0.0, 0.0));
  int tripped_at = -1;
  for (int k = 1; k <= 20 && tripped_at < 0; ++k)
    if (g.update(no_report(0.05 * k)) == EncoderFault::stale) tripped_at = k;
  EXPECT_EQ(tripped_at, 11);  // stale_periods = 10 are tolerated
  EXPECT_STREQ(g.message(), "x: no encoder report for 11 periods while moving (limit 10)");
}

TEST(EncoderGuard, FollowingErrorTrips) {
  auto g = make_guard();
  double enc = 0.0;
  EncoderFault f = EncoderFault::none;
  int k = 0;
  for (; k < 100 && f == EncoderFault::none; ++k) {
    enc += 0.05;                                 // the carriage lags a reference at 0.1 mm/period
    f = g.update(report(enc, 0.1 * (k + 1)));    // error 0.05 (k + 1)
  }
  EXPECT_EQ(f, EncoderFault::following_error);
  EXPECT_EQ(k, 41);  // first error above 2 mm: 0.05 x 41 = 2.05
  EXPECT_STREQ(g.message(), "x: following error 2.050 mm (limit 2.000 mm)");
  EXPECT_STREQ(fc::to_string(g.fault()), "following_error");
}

TEST(EncoderGuard, RejectsBadParameters) {
  fc::EncoderGuard g;
  fc::EncoderGuardParams p;
  p.max_jump_mm = 0.0;
  auto s = g.configure(p);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("max_jump_mm"), std::string::npos);
  p = fc::EncoderGuardParams{};
  p.stale_periods = 0;
  EXPECT_FALSE(g.configure(p).ok());
  p = fc::EncoderGuardParams{};
  p.axis = "a_very_long_axis_name";
  ASSERT_TRUE(g.configure(p).ok());
  g.update(report(0.0, 0.0));
  g.update(report(0.0, 5.0));
  EXPECT_STREQ(g.message(), "a_very_: following error 5.000 mm (limit 2.000 mm)");
}
