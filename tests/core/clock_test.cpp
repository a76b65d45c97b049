#include "core/clock.hpp"

#include <gtest/gtest.h>

namespace feedloop {

TEST(VirtualClock, AdvancesOnlyWhenSleeping) {
  VirtualClock clock(1000);
  EXPECT_EQ(clock.now_ns(), 1000);
  clock.sleep_until_ns(5000);
  EXPECT_EQ(clock.now_ns(), 5000);
  clock.sleep_until_ns(2000);  // a deadline in the past does not move time back
  EXPECT_EQ(clock.now_ns(), 5000);
  clock.advance_ns(10);
  EXPECT_EQ(clock.now_ns(), 5010);
}

TEST(MonotonicClock, SleepsUntilAnAbsoluteDeadline) {
  MonotonicClock clock;
  const int64_t t0 = clock.now_ns();
  clock.sleep_until_ns(t0 + 2'000'000);
  const int64_t t1 = clock.now_ns();
  EXPECT_GE(t1 - t0, 2'000'000);
}

TEST(ClockConversions, RoundTrip) {
  EXPECT_EQ(ns_from_seconds(1.5), 1'500'000'000);
  EXPECT_EQ(ns_from_seconds(-0.25), -250'000'000);
  EXPECT_DOUBLE_EQ(seconds_from_ns(2'500'000'000), 2.5);
}

}  // namespace feedloop
