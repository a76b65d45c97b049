// Each protection rule on synthetic temperature traces: it trips at the rule's time with its
// numbers, and not a sample earlier.
#include <gtest/gtest.h>

#include <string>

#include "thermal/protection.hpp"

namespace feedloop::thermal {
namespace {

constexpr double kAdcMid = 0.5;

TEST(Protection, RunawayTripsAfter40sMoreThan4CBelowTargetOnceReached) {
  ThermalProtection p;
  double t = 0;
  ThermalFault f;
  // Heat up from 200 to 210 (reaches the target), then drop to 205.4 and stay there.
  for (; t < 30; t += 0.5)
    f = p.check(t, std::min(210.0, 200.0 + t), 210.0, kAdcMid + t * 1e-4, true);
  EXPECT_FALSE(f);
  const double drop_t = t;
  for (; t < drop_t + 39.5; t += 0.5) f = p.check(t, 205.4, 210.0, kAdcMid + t * 1e-4, true);
  EXPECT_FALSE(f);
  for (; t < drop_t + 41; t += 0.5) {
    f = p.check(t, 205.4, 210.0, kAdcMid + t * 1e-4, true);
    if (f) break;
  }
  ASSERT_EQ(f.rule, ThermalRule::kRunaway);
  EXPECT_NEAR(f.t_s - drop_t, 40.0, 0.51);
  char buf[200];
  EXPECT_EQ(std::string(describe(f, buf, sizeof buf)),
            "thermal runaway: 4.6 C below target for 40.0 s (hysteresis 4.0 C)");
}

TEST(Protection, HeatingWatchTripsWhenTwoDegreesAreNotGainedIn20s) {
  ProtectionParams pp;
  pp.verify_max_error_cs = 0;  // isolate Marlin's rule
  ThermalProtection p(pp);
  ThermalFault f;
  double t = 0;
  for (; t <= 25 && !f; t += 0.25)
    f = p.check(t, 30.0 + 0.09 * t, 210.0, kAdcMid + t * 1e-4, true);  // +1.8 C / 20 s
  ASSERT_EQ(f.rule, ThermalRule::kHeatingWatch);
  EXPECT_NEAR(f.t_s, 20.0, 0.01);
  // 0.11 C/s passes: 2.2 C per 20 s, re-armed every 20 s.
  ThermalProtection ok(pp);
  for (t = 0; t < 200; t += 0.25)
    ASSERT_FALSE(ok.check(t, 30.0 + 0.11 * t, 210.0, kAdcMid + t * 1e-4, true));
}

TEST(Protection, KlipperVerifyHeaterTripsAfter120DegreeSecondsOnceNoLongerApproaching) {
  ProtectionParams pp;
  pp.watch_period_s = 0;
  pp.runaway_period_s = 0;
  ThermalProtection p(pp);
  ThermalFault f;
  // Stuck at 180 C with a 210 C target: approaching for 20 s (gain check), then error 25 C per s.
  double t = 0;
  for (; t < 60 && !f; t += 1.0) f = p.check(t, 180.0, 210.0, kAdcMid + t * 1e-4, true);
  ASSERT_EQ(f.rule, ThermalRule::kVerifyHeater);
  // error accumulates 25/s from t=0; the check at t=20 ends the approach; fault at the first
  // second the error reaches 120 after that: t = 21 (error 550 by then).
  EXPECT_NEAR(f.t_s, 21.0, 1e-9);
  EXPECT_GE(f.a, 120.0);
}

TEST(Protection, SensorRangeAndStuckRules) {
  ThermalProtection open, shrt, hot, cold, stuck;
  EXPECT_EQ(open.check(0, -50, 200, 0.999, true).rule, ThermalRule::kSensorOpen);
  EXPECT_EQ(shrt.check(0, 500, 200, 0.001, true).rule, ThermalRule::kSensorShort);
  EXPECT_EQ(hot.check(0, 301, 200, 0.02, true).rule, ThermalRule::kMaxTemp);
  EXPECT_EQ(cold.check(0, -1, 200, 0.98, true).rule, ThermalRule::kMinTemp);
  ThermalFault f;
  double t = 0;
  for (; t < 30 && !f; t += 0.3) f = stuck.check(t, 210.0, 210.0, 0.0312, true);
  ASSERT_EQ(f.rule, ThermalRule::kStuckSensor);
  EXPECT_NEAR(f.t_s, 10.2, 0.31);
  // A latched fault stays until reset().
  EXPECT_EQ(stuck.check(40, 210, 210, 0.03, true).rule, ThermalRule::kStuckSensor);
  stuck.reset();
  EXPECT_FALSE(stuck.check(41, 210, 210, 0.03, true));
}

TEST(Protection, HeaterOffNeverTripsTheHeatingRules) {
  ThermalProtection p;
  for (double t = 0; t < 600; t += 0.3) ASSERT_FALSE(p.check(t, 25.0, 0.0, 0.95, false));
}

}  // namespace
}  // namespace feedloop::thermal
