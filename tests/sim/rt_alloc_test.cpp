// The plants' MotorPort calls (step, set_enabled, read_encoder_counts) and advance_to() allocate
// nothing, so the virtual MCU can call them from a real-time loop. malloc is counted by
// interposing it (skipped under sanitizers, which own malloc).
#include <atomic>
#include <cstddef>

#include <gtest/gtest.h>

#include "sim/delta_plant.hpp"
#include "sim/gantry_axis.hpp"

#include "tests/common/malloc_counter.hpp"

namespace feedloop::sim {
namespace {

TEST(SimRt, GantryAndDeltaCallsDoNotAllocate) {
#ifndef FEEDLOOP_COUNT_MALLOC
  GTEST_SKIP() << "malloc counting needs glibc and no sanitizer";
#else
  GantryAxisParams gp = thesis_x_axis();
  gp.effects.time_delay = {true, 2.0};  // exercises the history ring
  gp.effects.coulomb_friction = {true, 1.0};
  GantryAxis axis = std::move(GantryAxis::create(gp).value());
  DeltaPlantParams dp;
  dp.encoder.sampling_delay_s = 1e-4;
  auto delta = std::move(DeltaPlant::create(dp).value());
  long counts = 0;
  g_mallocs = 0;
  g_counting = true;
  for (int k = 1; k <= 2000; ++k) {
    const double t = k * 1e-4;
    axis.step(t, 1);
    delta->carriage_port(k % 3).step(t, 1);
    if (k % 10 == 0) {
      counts += axis.read_encoder_counts(t);
      for (int i = 0; i < 3; ++i) counts += delta->carriage_port(i).read_encoder_counts(t);
    }
  }
  axis.set_enabled(0.3, false);
  delta->carriage_port(0).set_enabled(0.3, true);
  g_counting = false;
  EXPECT_EQ(g_mallocs.load(), 0);
  EXPECT_GT(counts, 0);  // the plants moved
#endif
}

}  // namespace
}  // namespace feedloop::sim
