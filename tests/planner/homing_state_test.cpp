// Homing state in the interpreter, as Marlin and Klipper document it:
//  - travel limits only after homing: a move of an unhomed axis is refused ("Must home axis
//    first", Klipper's cartesian.py / Marlin's NO_MOTION_BEFORE_HOMING) and moves nothing;
//  - G28 with axis letters homes those axes only; a delta homes every tower (Klipper delta.py);
//  - M18/M84 without S disable the steppers and the axes must be homed again (Marlin's M18_M84
//    doc: "Disable steppers ... the axes will need to be homed again"); M84 S<seconds> only sets
//    the idle timeout; M84 E keeps XYZ homed;
//  - M201/M203 change the per-axis limits at runtime (marlinfw.org/docs/gcode/M201.html,
//  M203.html);
//  - planner.allow_moves_before_homing: true keeps the old behaviour (the machine starts homed).
#include <gtest/gtest.h>

#include <cstring>

#include "planner_test_util.hpp"

namespace feedloop::planner {
namespace {

using test::Rig;

PlannerConfig needs_homing(PlannerConfig c) {
  c.allow_moves_before_homing = false;
  return c;
}

std::string homed(const Rig& r) {
  char b[4];
  r.interp.homed_axes(b);
  return b;
}

TEST(HomingState, MoveBeforeHomingIsRefusedWithAClearError) {
  Rig r(needs_homing(test::cartesian_config()));
  EXPECT_EQ(homed(r), "");
  const Status s = r.run("G1 X10 Y5 F3000");
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("Must home axis first (XY not homed"), std::string::npos)
      << s.error().message;
  EXPECT_NE(s.error().message.find("G28"), std::string::npos);
  EXPECT_EQ(s.error().where.line, 1);      // the location of the line
  EXPECT_EQ(r.planner.moves_added(), 0u);  // nothing executed
  EXPECT_DOUBLE_EQ(r.interp.state().machine_mm[kX], 0.0);
  // Arcs too.
  EXPECT_FALSE(r.run("G2 X10 Y0 I5 J0").ok());
  // E needs no homing (an extruder has no endstop).
  EXPECT_TRUE(r.run("G1 E5 F600").ok());
  EXPECT_EQ(r.planner.moves_added(), 1u);
  // G10 with a Z lift moves Z: refused; without lift it is an E move.
  ASSERT_TRUE(r.run("M207 S1 Z0.4").ok());
  EXPECT_FALSE(r.run("G10").ok());
  ASSERT_TRUE(r.run("M207 Z0").ok());
  EXPECT_TRUE(r.run("G10").ok());
}

TEST(HomingState, G28PerAxisThenAll) {
  Rig r(needs_homing(test::cartesian_config()));
  ASSERT_TRUE(r.run("G28 X").ok());
  EXPECT_EQ(homed(r), "x");
  EXPECT_TRUE(r.run("G1 X20 F3000").ok());
  const Status s = r.run("G1 X30 Y10");
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("(Y not homed"), std::string::npos) << s.error().message;
  EXPECT_DOUBLE_EQ(r.interp.state().machine_mm[kX], 20.0);  // the refused line changed nothing
  ASSERT_TRUE(r.run("G28").ok());
  EXPECT_EQ(homed(r), "xyz");
  EXPECT_TRUE(r.run("G1 X30 Y10 Z5").ok());
  // Travel limits still apply after homing.
  EXPECT_FALSE(r.run("G1 X500").ok());
}

// PrusaSlicer's `G28 W` (Prusa-Firmware: home without the mesh levelling after it) homes every
// axis, as G28 does.
TEST(HomingState, PrusasG28WHomesEveryAxis) {
  Rig r(needs_homing(test::cartesian_config()));
  ASSERT_TRUE(r.run("G28 W").ok());
  EXPECT_EQ(homed(r), "xyz");
  EXPECT_TRUE(r.run("G1 X30 Y10 Z5 F3000").ok());
}

TEST(HomingState, MotorsOffUnhomesAsMarlin) {
  Rig r(needs_homing(test::cartesian_config()));
  ASSERT_TRUE(r.run("G28").ok());
  ASSERT_TRUE(r.run("M84 S30").ok());  // timeout only
  EXPECT_EQ(homed(r), "xyz");
  ASSERT_TRUE(r.run("M84 E").ok());  // the extruder only
  EXPECT_EQ(homed(r), "xyz");
  ASSERT_TRUE(r.run("M18 X").ok());  // M18 = M84
  EXPECT_EQ(homed(r), "yz");
  EXPECT_FALSE(r.run("G1 X5").ok());
  EXPECT_TRUE(r.run("G1 Y5 F3000").ok());
  ASSERT_TRUE(r.run("M84").ok());
  EXPECT_EQ(homed(r), "");
  EXPECT_FALSE(r.run("G1 Y6").ok());
}

TEST(HomingState, DeltaHomesAndRefusesAllTowersTogether) {
  Rig r(needs_homing(test::delta_config()));
  const Status s = r.run("G1 Z200 F3000");  // one Cartesian axis moves every carriage
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("XYZ not homed"), std::string::npos) << s.error().message;
  ASSERT_TRUE(r.run("G28 Z").ok());  // a delta always homes all towers
  EXPECT_EQ(homed(r), "xyz");
  EXPECT_TRUE(r.run("G1 X10 Z200").ok());
  ASSERT_TRUE(r.run("M84 X").ok());  // a delta's towers are disabled together
  EXPECT_EQ(homed(r), "");
}

TEST(HomingState, AllowFlagKeepsTheOldBehaviour) {
  Rig r(test::cartesian_config());  // allow_moves_before_homing: true
  EXPECT_EQ(homed(r), "xyz");
  EXPECT_TRUE(r.run("G1 X10 F3000").ok());
  ASSERT_TRUE(r.run("M84").ok());
  EXPECT_EQ(homed(r), "xyz");
  EXPECT_TRUE(r.run("G1 X20").ok());
}

TEST(RuntimeLimits, M203CapsTheAxisSpeedAndM201ItsAcceleration) {
  // Marlin M203: "Set maximum feedrate for one or more axes" in units/s; M201: max acceleration
  // in units/s^2. A later move along X alone is planned within the new limits.
  Rig r(test::cartesian_config());
  ASSERT_TRUE(r.run("M203 X20").ok());
  ASSERT_TRUE(r.run("M201 X400").ok());
  ASSERT_TRUE(r.run("G1 X100 F12000").ok());  // 200 mm/s asked
  r.planner.flush();
  ASSERT_EQ(r.rec.moves.size(), 1u);
  EXPECT_NEAR(r.rec.moves[0].v_cruise_mm_s, 20.0, 1e-9);
  EXPECT_LE(r.rec.moves[0].accel_mm_s2, 400.0 + 1e-9);
  EXPECT_GT(r.rec.moves[0].accel_mm_s2, 399.0);
  // A non-positive limit is refused and changes nothing.
  EXPECT_FALSE(r.run("M203 X0").ok());
  ASSERT_TRUE(r.run("G1 X0").ok());
  r.planner.flush();
  ASSERT_EQ(r.rec.moves.size(), 2u);
  EXPECT_NEAR(r.rec.moves[1].v_cruise_mm_s, 20.0, 1e-9);
}

}  // namespace
}  // namespace feedloop::planner
