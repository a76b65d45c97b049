// M84 on a delta (the end of every slicer's delta file): the drivers off let the carriages slide
// under the effector's weight. The device loops go off with the drivers and get no targets until
// the drivers are on again; before, a loop still running read the slide as a following error and
// stopped the MCU after the print had ended (CorpusSlip on benchy_delta: "following error beyond
// the limit" 5 s after its M84).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "config/config.hpp"
#include "engine/sim_run.hpp"

namespace feedloop::engine {
namespace {

TEST(MotorsOff, ADeltaSlidingWithItsDriversOffIsNoFault) {
  auto delta = config::load_config_file(std::string(FEEDLOOP_SOURCE_DIR) +
                                        "/config/examples/delta_sim.yaml");
  ASSERT_TRUE(delta.ok()) << delta.error().to_string();
  ASSERT_FALSE(delta->planner.allow_moves_before_homing);  // else M84 keeps the drivers on
  const std::vector<std::string> lines = {"G28", "G1 X10 Y10 Z100 F6000", "G1 X0 Y0 Z150 F6000",
                                          "M84", "G4 P3000"};
  SimRunOptions o;
  o.keep_samples = false;
  auto r = run_simulated(*delta, lines, o);
  ASSERT_TRUE(r.ok()) << r.error().to_string();
  EXPECT_EQ(r->error, "");
  EXPECT_EQ(r->faults, 0u);
  EXPECT_EQ(r->commands, lines.size());
  for (int j = 0; j < 3; ++j) {
    EXPECT_TRUE(r->device_loops[static_cast<size_t>(j)].enabled) << "joint " << j;  // loops ran
    EXPECT_EQ(r->device_loops[static_cast<size_t>(j)].slips, 0u) << "joint " << j;
  }
}

}  // namespace
}  // namespace feedloop::engine
