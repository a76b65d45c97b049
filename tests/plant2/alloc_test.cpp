// The second simulator's stepping allocates nothing after create() (flat state, a delay line of
// fixed capacity): it can run inside a real-time loop. malloc is counted by interposing it
// (skipped under sanitizers, which own malloc).
#include <gtest/gtest.h>

#include <cmath>
#include <utility>

#include "plant2/axis2.hpp"
#include "plant2/draw.hpp"

#include "tests/common/malloc_counter.hpp"

namespace feedloop::plant2 {
namespace {

TEST(Plant2Alloc, SteppingAndReadingDoNotAllocate) {
#ifndef FEEDLOOP_COUNT_MALLOC
  GTEST_SKIP() << "malloc counting needs glibc and no sanitizer";
#else
  for (EffectKind kind : kAllEffectKinds) {
    Axis2 axis = std::move(Axis2::create(draw_axis(5, kind).params).value());
    double sum = 0.0;
    g_mallocs = 0;
    g_counting = true;
    for (int k = 1; k <= 2000; ++k) {
      axis.advance(0.1 + 1e-3 * std::sin(0.01 * k), 1e-4);
      sum += axis.measured_m() + axis.measured_quantised_m();
    }
    g_counting = false;
    EXPECT_EQ(g_mallocs.load(), 0) << effect_name(kind);
    EXPECT_TRUE(std::isfinite(sum));
  }
#endif
}

}  // namespace
}  // namespace feedloop::plant2
