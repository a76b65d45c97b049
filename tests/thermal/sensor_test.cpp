// Sensor conversions against datasheet points (Semitec 104GT-2, EPCOS B57560G104F, PT1000).
#include <gtest/gtest.h>

#include <cmath>

#include "thermal/sensor.hpp"

namespace feedloop::thermal {
namespace {

TEST(Sensor, Semitec104Gt2MatchesItsDatasheetPointsAndOnesBetween) {
  const auto s = builtin_sensor("Semitec 104GT-2");
  ASSERT_TRUE(s);
  EXPECT_NEAR(resistance_at(*s, 20), 126800, 1.0);
  EXPECT_NEAR(resistance_at(*s, 300), 80.65, 0.01);
  EXPECT_NEAR(temp_at_resistance(*s, 1360), 150.0, 1e-6);
  // Datasheet: 100 kohm at 25 C, B25/85 = 4267 K (R = 5.63 kohm at 100 C by the beta form): the
  // three-point fit lies within 2.5 C of both.
  EXPECT_NEAR(temp_at_resistance(*s, 100000), 25.0, 1.5);
  EXPECT_NEAR(temp_at_resistance(*s, 5634), 100.0, 2.5);
}

TEST(Sensor, EpcosRoundTripsThroughTheDivider) {
  const auto s = builtin_sensor("EPCOS 100K B57560G104F");
  ASSERT_TRUE(s);
  EXPECT_NEAR(temp_at_resistance(*s, 100000), 25.0, 1e-6);
  EXPECT_NEAR(temp_at_resistance(*s, 1641.9), 150.0, 1e-6);
  for (double t = 0; t <= 300; t += 7.5) EXPECT_NEAR(temp_at_adc(*s, adc_at(*s, t)), t, 1e-6) << t;
  // Hotter reads lower on a divider with the NTC to ground.
  EXPECT_GT(adc_at(*s, 25), 0.95);
  EXPECT_LT(adc_at(*s, 250), 0.05);
}

TEST(Sensor, Pt1000FollowsCallendarVanDusen) {
  const auto s = builtin_sensor("PT1000");
  ASSERT_TRUE(s);
  EXPECT_NEAR(resistance_at(*s, 0), 1000.0, 1e-9);
  EXPECT_NEAR(resistance_at(*s, 100), 1385.1, 0.1);  // IEC 60751 table
  EXPECT_NEAR(resistance_at(*s, 300), 2120.5, 0.2);
  EXPECT_NEAR(temp_at_adc(*s, adc_at(*s, 255.0)), 255.0, 1e-6);
}

TEST(Sensor, BetaFormAndInvalidInputs) {
  const auto b = beta_thermistor(25, 100000, 3950);
  ASSERT_TRUE(b);
  EXPECT_NEAR(temp_at_resistance(*b, 100000), 25.0, 1e-9);
  // R(T) = R0 exp(beta (1/T - 1/T0)) at 100 C.
  const double r100 = 100000 * std::exp(3950 * (1 / 373.15 - 1 / 298.15));
  EXPECT_NEAR(temp_at_resistance(*b, r100), 100.0, 1e-6);
  EXPECT_FALSE(beta_thermistor(25, -1, 3950));
  EXPECT_FALSE(steinhart_hart(25, 100000, 25, 100000, 250, 200));
  EXPECT_FALSE(builtin_sensor("NTC 42"));
  EXPECT_TRUE(std::isinf(temp_at_adc(*b, 0.0)) && temp_at_adc(*b, 0.0) > 0);  // short: +inf
  EXPECT_TRUE(std::isinf(temp_at_adc(*b, 1.0)) && temp_at_adc(*b, 1.0) < 0);  // open: -inf
}

}  // namespace
}  // namespace feedloop::thermal
