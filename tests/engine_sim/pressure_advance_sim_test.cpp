// Pressure advance through the daemon's motion executor on the simulated printer (the exact path,
// and the sampled path of the closed-loop default): the extruder is ahead by about K v while it
// extrudes, X and Y make the same steps (shifted by the half window the motion starts later), the
// extruder ends on exactly the same step count, every step executed once; with K = 0 the
// extruder's steps are those of a run without any M900.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "engine/servo_control.hpp"
#include "sim_rig.hpp"

namespace feedloop::engine {
namespace {

using testing::SimRig;

// 50 mm/s with 0.05 mm of filament per mm: 2.5 mm/s of filament (240 steps/s at 96 steps/mm).
constexpr const char* kMoves =
    "G1 X10 Y10 F6000\n"
    "G1 X60 Y10 E2.5 F3000\n"
    "G1 X60 Y60 E5.0\n"
    "G1 X10 Y60 E7.5\n"
    "G1 E6.7 F2400\n"
    "G1 X10 Y10 F6000\n";

// The motor's position as its MCU executed it, in steps.
int64_t executed(SimRig& rig, int joint) {
  const int m = rig.bridge->mcu_of_joint(joint);
  return rig.bridge->virtual_mcu(m)
      ->status()
      .axes[rig.bridge->motor_of_joint(joint)]
      .position_steps;
}

struct Trace {
  std::vector<int64_t> e, x, y;  // executed step positions per servo cycle
  int64_t final_e = 0, final_x = 0, final_y = 0;
  uint64_t e_steps = 0;
};

Trace run(const std::string& prefix, bool sampled) {
  SimRig rig(config::default_config());
  if (sampled) {
    auto c = make_servo_control(rig.cfg);
    EXPECT_TRUE(c.ok());
    rig.ex->set_control(std::move(c.value()));
  }
  EXPECT_TRUE(rig.wait_ready());
  EXPECT_EQ(rig.execute(prefix + kMoves), "");
  Trace t;
  for (int i = 0; i < 30000 && (rig.ex->motion_pending() || i < 100); ++i) {
    rig.cycle();
    t.e.push_back(executed(rig, 3));
    t.x.push_back(executed(rig, 0));
    t.y.push_back(executed(rig, 1));
  }
  rig.run_for(0.5);
  EXPECT_FALSE(rig.ex->motion_pending());
  t.final_e = executed(rig, 3);
  t.final_x = executed(rig, 0);
  t.final_y = executed(rig, 1);
  EXPECT_EQ(t.final_e, rig.ex->steps().position_steps(3));
  t.e_steps = rig.ex->steps().stats(3).steps;
  for (int j = 0; j < kJoints; ++j) {  // every step generated was executed once
    const JointTiming& jt = rig.bridge->timing(j);
    EXPECT_EQ(jt.steps_sent, rig.ex->steps().stats(j).steps) << j;
    EXPECT_EQ(jt.unexpected_steps, 0u) << j;
    EXPECT_EQ(rig.ex->steps().stats(j).check_failures, 0u) << j;
  }
  return t;
}

// The largest lead of `a` over `b` (a shifted back by `shift` cycles).
int64_t max_lead(const Trace& a, const Trace& b, size_t shift) {
  int64_t lead = 0;
  for (size_t i = 0; i + shift < a.e.size() && i < b.e.size(); ++i)
    lead = std::max(lead, a.e[i + shift] - b.e[i]);
  return lead;
}

void check(bool sampled) {
  const Trace plain = run("", sampled);
  const Trace zero = run("M900 K0\n", sampled);
  const Trace pa = run("M900 K0.06\n", sampled);  // smooth_time 0.040 s: h = 20 ms = 20 cycles
  // K = 0 is the old path: the same steps at the same cycles.
  EXPECT_EQ(zero.e, plain.e);
  EXPECT_EQ(zero.x, plain.x);
  // No step lost or added: the same end, and the extruder made only the steps to get there and
  // back (7.5 mm out, 0.8 mm retracted: 720 + 77 steps, plus at most a few reversals at corners).
  EXPECT_EQ(pa.final_e, plain.final_e);
  EXPECT_EQ(pa.final_x, plain.final_x);
  EXPECT_EQ(pa.final_y, plain.final_y);
  EXPECT_EQ(plain.final_e, 643);  // 6.7 mm x 96 steps/mm
  std::printf("%s: extruder steps made %llu without, %llu with the advance\n",
              sampled ? "sampled" : "exact", static_cast<unsigned long long>(plain.e_steps),
              static_cast<unsigned long long>(pa.e_steps));
  EXPECT_LE(pa.e_steps, plain.e_steps + 40);
  // X and Y: the same steps, 20 cycles later (the motion starts half a window later).
  const size_t shift = 20;
  int64_t xy_diff = 0;
  for (size_t i = 0; i + shift < pa.x.size() && i < plain.x.size(); ++i)
    xy_diff = std::max(
        {xy_diff, std::abs(pa.x[i + shift] - plain.x[i]), std::abs(pa.y[i + shift] - plain.y[i])});
  EXPECT_LE(xy_diff, 1);
  // The extruder leads by K v = 0.06 s x 2.5 mm/s = 0.15 mm = 14.4 steps while it extrudes at
  // 50 mm/s (the lead builds with the acceleration, the window rounds it).
  const int64_t lead = max_lead(pa, plain, shift);
  std::printf("%s: max extruder lead %lld steps (K v = 14.4)\n", sampled ? "sampled" : "exact",
              static_cast<long long>(lead));
  EXPECT_GE(lead, 12);
  EXPECT_LE(lead, 20);
}

TEST(PressureAdvanceSim, ExactPathAdvancesTheExtruderAndLosesNoStep) {
  check(false);
}
TEST(PressureAdvanceSim, SampledPathAdvancesTheExtruderAndLosesNoStep) {
  check(true);
}

}  // namespace
}  // namespace feedloop::engine
