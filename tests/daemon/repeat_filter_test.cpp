// The daemon's repeated-warning filter: one line plus a count instead of the same line per command.
#include "daemon/repeat_filter.hpp"

#include <gtest/gtest.h>

namespace feedloop::daemon {
namespace {

constexpr int64_t kMs = 1'000'000;

TEST(RepeatFilter, TheSameWarning199TimesIsOneLinePlusACount) {
  RepeatFilter f(10'000 * kMs);
  std::string summary;
  int logged = 0;
  for (int i = 0; i < 199; ++i) {
    if (f.admit("motion stopped: x encoder implausible", i * 20 * kMs, &summary)) ++logged;
    EXPECT_TRUE(summary.empty());
  }
  EXPECT_EQ(logged, 1);
  EXPECT_EQ(f.flush(199 * 20 * kMs), "");  // 4 s: still inside the window
  // A different message reports the repeats first, then is logged itself.
  EXPECT_TRUE(f.admit("X5000 is outside the travel limits", 4000 * kMs, &summary));
  EXPECT_EQ(summary, "last message repeated 198 times in 4.0 s: motion stopped: x encoder implausible");
  EXPECT_EQ(f.suppressed_total(), 198u);
}

TEST(RepeatFilter, TheCountIsReportedWhenTheWindowEndsAndTheKeyLogsAgain) {
  RepeatFilter f(1000 * kMs);
  std::string summary;
  EXPECT_TRUE(f.admit("a", 0, &summary));
  EXPECT_FALSE(f.admit("a", 100 * kMs, &summary));
  EXPECT_FALSE(f.admit("a", 200 * kMs, &summary));
  EXPECT_EQ(f.flush(500 * kMs), "");
  EXPECT_EQ(f.flush(1000 * kMs), "last message repeated 2 times in 0.2 s: a");
  EXPECT_EQ(f.flush(1500 * kMs), "");
  EXPECT_TRUE(f.admit("a", 1600 * kMs, &summary));  // a new window: logged again
  EXPECT_TRUE(summary.empty());
}

}  // namespace
}  // namespace feedloop::daemon
