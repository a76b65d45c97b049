// The discrete filter used in the servo thread: step() allocates nothing (malloc is counted by
// interposing it; skipped under sanitizers, which own malloc), and its step response settles to
// the static gain 1 of the position-to-position gantry model.
#include <gtest/gtest.h>

#include <atomic>
#include <cstddef>

#include "model/discrete.hpp"
#include "model/gantry_axis.hpp"

#include "tests/common/malloc_counter.hpp"

namespace fm = feedloop::model;

TEST(DiscreteFilter, StepResponseSettlesToOne) {
  auto d = fm::discretize_zoh(fm::gantry_state_space(fm::thesis_x_axis()), 1e-3);
  ASSERT_TRUE(d.ok());
  fm::DiscreteLtiFilter f;
  ASSERT_TRUE(f.configure(*d).ok());
  const double u = 1.0;
  double y = 0.0;
  for (int k = 0; k < 2000; ++k) f.step(&u, &y);  // slowest pole ~ -40 rad/s
  EXPECT_NEAR(y, 1.0, 1e-6);
  f.reset_to_steady_state(&u);
  f.step(&u, &y);
  EXPECT_NEAR(y, 1.0, 1e-9);
  f.reset();
  f.step(&u, &y);
  EXPECT_EQ(y, 0.0);  // D = 0: the first output only sees the zero state
}

TEST(DiscreteFilter, StepDoesNotAllocate) {
#ifndef FEEDLOOP_COUNT_MALLOC
  GTEST_SKIP() << "malloc counting is off under sanitizers / non-glibc";
#else
  // Sanity: the counter sees an Eigen allocation.
  g_counting = true;
  { Eigen::VectorXd v(1000); v.setZero(); EXPECT_EQ(v.size(), 1000); }
  g_counting = false;
  ASSERT_GT(g_mallocs.load(), 0);
  g_mallocs = 0;

  auto d = fm::discretize_zoh(fm::gantry_state_space(fm::thesis_y_axis()), 1e-3);
  ASSERT_TRUE(d.ok());
  fm::DiscreteLtiFilter f;
  ASSERT_TRUE(f.configure(*d).ok());
  double u = 0.0, y = 0.0, sum = 0.0;
  g_counting = true;
  for (int k = 0; k < 1000; ++k) {
    u = (k % 100) * 0.01;
    f.step(&u, &y);
    sum += y;
  }
  f.reset_to_steady_state(&u);
  f.reset();
  g_counting = false;
  EXPECT_EQ(g_mallocs.load(), 0);
  EXPECT_GT(sum, 0.0);
#endif
}
