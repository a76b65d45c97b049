// Interpreter semantics: G90/G91, M82/M83, G92, G20, M204 P/R/T/S, M220/M221, G4, M400, G10/G11,
// arcs (I J and R) within the chordal tolerance, and whole-command rejection.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>

#include "planner/junction.hpp"
#include "planner_test_util.hpp"

namespace feedloop::planner {
namespace {

using test::Rig;

// E amounts for the arithmetic, not printable tracks: without the extrusion bounds.
PlannerConfig unbounded_extrusion() {
  PlannerConfig c = test::cartesian_config();
  c.max_extrude_cross_section_mm2 = 0.0;
  return c;
}

TEST(Interpreter, RelativeAndAbsoluteModes) {
  Rig r(unbounded_extrusion());
  ASSERT_TRUE(r.run("G28"));
  ASSERT_TRUE(r.run("G1 X10 Y10 F6000"));
  ASSERT_TRUE(r.run("G91"));
  ASSERT_TRUE(r.run("G1 X5 E2"));  // G91 makes E relative too (Marlin)
  EXPECT_DOUBLE_EQ(r.interp.state().machine_mm[kX], 15.0);
  EXPECT_DOUBLE_EQ(r.interp.state().machine_mm[kE], 2.0);
  ASSERT_TRUE(r.run("M82"));  // E absolute while XYZ stay relative
  ASSERT_TRUE(r.run("G1 X1 E3"));
  EXPECT_DOUBLE_EQ(r.interp.state().machine_mm[kX], 16.0);
  EXPECT_DOUBLE_EQ(r.interp.state().machine_mm[kE], 3.0);
  ASSERT_TRUE(r.run("G90"));  // resets E to follow XYZ: absolute
  ASSERT_TRUE(r.run("M83"));
  ASSERT_TRUE(r.run("G1 X20 E1"));
  EXPECT_DOUBLE_EQ(r.interp.state().machine_mm[kX], 20.0);
  EXPECT_DOUBLE_EQ(r.interp.state().machine_mm[kE], 4.0);
}

TEST(Interpreter, G92SetsLogicalPositionWithoutMoving) {
  Rig r(unbounded_extrusion());
  ASSERT_TRUE(r.run("G1 X10 E5 F3000"));
  const uint64_t before = r.planner.moves_added();
  ASSERT_TRUE(r.run("G92 E0"));
  ASSERT_TRUE(r.run("G92 X100"));
  EXPECT_EQ(r.planner.moves_added(), before);
  ASSERT_TRUE(r.run("G1 X110 E1"));  // +10 in X, +1 in E
  EXPECT_DOUBLE_EQ(r.interp.state().machine_mm[kX], 20.0);
  EXPECT_DOUBLE_EQ(r.interp.state().machine_mm[kE], 6.0);
  EXPECT_DOUBLE_EQ(r.interp.state().logical_mm[kX], 110.0);
  ASSERT_TRUE(r.run("G20"));
  ASSERT_FALSE(r.run("G1 X110.1").ok());  // 110.1 in is far outside the bed: rejected
  EXPECT_DOUBLE_EQ(r.interp.state().machine_mm[kX], 20.0);
  ASSERT_TRUE(r.run("G21"));
}

// One extruder: T0 is a no-op (slicers send it first), another tool is refused with its name
// and changes nothing (a two-colour file would otherwise print both colours with one filament).
TEST(Interpreter, AnotherToolThanT0IsRefusedAndChangesNothing) {
  Rig r(unbounded_extrusion());
  ASSERT_TRUE(r.run("G28"));
  ASSERT_TRUE(r.run("T0"));
  ASSERT_TRUE(r.run("G1 X10 E1 F3000"));
  const uint64_t before = r.planner.moves_added();
  const Status t1 = r.run("T1");
  ASSERT_FALSE(t1.ok());
  EXPECT_NE(t1.error().to_string().find("T1: this machine has one extruder (T0)"),
            std::string::npos)
      << t1.error().to_string();
  EXPECT_EQ(r.planner.moves_added(), before);
  ASSERT_TRUE(r.run("G1 X20 E2"));
  EXPECT_DOUBLE_EQ(r.interp.state().machine_mm[kX], 20.0);
  EXPECT_DOUBLE_EQ(r.interp.state().machine_mm[kE], 2.0);
}

TEST(Interpreter, InchUnitsScaleCoordinatesAndFeedrate) {
  Rig r(test::cartesian_config());
  ASSERT_TRUE(r.run("G20"));
  ASSERT_TRUE(r.run("G1 X2 F600"));  // 50.8 mm at 600 in/min = 254 mm/s
  r.planner.flush();
  EXPECT_DOUBLE_EQ(r.interp.state().machine_mm[kX], 50.8);
  ASSERT_EQ(r.rec.moves.size(), 1u);
  EXPECT_NEAR(r.rec.moves[0].v_cruise_mm_s, 254.0, 1e-9);  // reachable: sqrt(a L / 2) = 276 > 254
}

// Two objects on the plate, labelled as a slicer labels them for Klipper; B is excluded before
// its turn (as from the web or the file). B's moves and retractions are skipped; the first move
// after it goes straight from where A ended; A's extrusion is whole and B's is not made up.
TEST(Interpreter, AnExcludedObjectsMovesAreSkippedAndItsExtrusionIsNotMadeUp) {
  Rig r(test::cartesian_config());
  ASSERT_TRUE(r.run("G28"));
  ASSERT_TRUE(r.run("M82"));
  ASSERT_TRUE(r.run("EXCLUDE_OBJECT_DEFINE NAME=a CENTER=50,50"));
  ASSERT_TRUE(r.run("EXCLUDE_OBJECT_DEFINE NAME=b CENTER=150,150"));
  ASSERT_TRUE(r.run("EXCLUDE_OBJECT NAME=B"));  // names compare upper-cased
  ASSERT_TRUE(r.run("G1 Z0.3 F600"));
  ASSERT_TRUE(r.run("EXCLUDE_OBJECT_START NAME=a"));
  ASSERT_TRUE(r.run("G1 X40 Y40 F6000"));
  ASSERT_TRUE(r.run("G1 X60 Y40 E1.0 F1800"));
  ASSERT_TRUE(r.run("G2 X60 Y60 I0 J10 E2.0"));
  ASSERT_TRUE(r.run("G10"));
  ASSERT_TRUE(r.run("EXCLUDE_OBJECT_END NAME=a"));
  const uint64_t moves_after_a = r.planner.moves_added();
  const double e_after_a = r.interp.state().machine_mm[kE];
  ASSERT_TRUE(r.run("EXCLUDE_OBJECT_START NAME=b"));
  ASSERT_TRUE(r.run("G11"));
  ASSERT_TRUE(r.run("G1 X140 Y140 F6000"));
  ASSERT_TRUE(r.run("G1 X160 Y140 E3.0 F1800"));
  ASSERT_TRUE(r.run("G92 E0"));
  ASSERT_TRUE(r.run("G1 X160 Y160 E1.5"));
  ASSERT_TRUE(r.run("G10"));
  ASSERT_TRUE(r.run("EXCLUDE_OBJECT_END NAME=b"));
  EXPECT_EQ(r.planner.moves_added(), moves_after_a);         // nothing of B moved
  EXPECT_EQ(r.interp.skipped_lines(), 5u);                   // G11, three G1, G10
  EXPECT_DOUBLE_EQ(r.interp.state().machine_mm[kX], 60.0);   // the machine is where A ended
  EXPECT_DOUBLE_EQ(r.interp.state().logical_mm[kX], 160.0);  // the G-code is where B ended
  ASSERT_TRUE(r.run("G11"));  // A's retraction recovered; B's was neither made nor recovered
  ASSERT_TRUE(r.run("G1 X20 Y20 E2.5 F1800"));  // +1.0 after B's E1.5 (G92 E0 inside B)
  EXPECT_DOUBLE_EQ(r.interp.state().machine_mm[kX], 20.0);
  EXPECT_NEAR(
      r.interp.state().machine_mm[kE],
      e_after_a + r.interp.state().retract_length_mm + r.interp.state().unretract_extra_mm + 1.0,
      1e-12);
  EXPECT_EQ(r.interp.objects().defined().size(), 2u);
  ASSERT_EQ(r.interp.objects().excluded().size(), 1u);
  EXPECT_EQ(r.interp.objects().excluded()[0], "B");
  // CURRENT=1 without a current object is an error naming it; RESET=1 prints every object again.
  auto s = r.run("EXCLUDE_OBJECT CURRENT=1");
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("no object is being printed"), std::string::npos);
  ASSERT_TRUE(r.run("EXCLUDE_OBJECT RESET=1"));
  EXPECT_TRUE(r.interp.objects().excluded().empty());
  // The lists are bounded: one object too many is refused and changes nothing.
  for (size_t i = r.interp.objects().defined().size(); i < ObjectLabels::kMaxObjects; ++i)
    ASSERT_TRUE(r.run("EXCLUDE_OBJECT_DEFINE NAME=o" + std::to_string(i)));
  s = r.run("EXCLUDE_OBJECT_START NAME=one_too_many");
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("too many objects"), std::string::npos);
  EXPECT_TRUE(r.interp.objects().current().empty());
  EXPECT_EQ(r.interp.objects().defined().size(), ObjectLabels::kMaxObjects);
}

// The same plate labelled as PrusaSlicer labels it for a Marlin printer (M486 index form): the
// header starts objects 0 and 1 and names them (M486 A, upper-cased, blanks as '_'; "M486 AP0" is
// a name, not a cancel); object 1 is cancelled by its index (M486 P1, as OctoPrint's
// Cancelobject or Marlin's menu sends it) and its moves are skipped; M486 C during object 0 skips
// the rest of it; M486 T starts a new plate, where an index is no name's alias any more.
TEST(Interpreter, MarlinsObjectIndexesAreExcludedAsKlippersNames) {
  Rig r(test::cartesian_config());
  EXPECT_TRUE(r.interp.objects().empty());
  for (const char* l : {"G28", "M83", "M486 T2", "M486 S0", "M486 AShape-Box id:0 copy 0",
                        "M486 S-1", "M486 S1", "M486 AP0", "M486 S-1", "G1 Z0.3 F600"})
    ASSERT_TRUE(r.run(l)) << l;
  const std::string box = "SHAPE-BOX_ID:0_COPY_0";
  EXPECT_EQ(r.interp.objects().defined(), (std::vector<std::string>{box, "P0"}));
  EXPECT_TRUE(r.interp.objects().excluded().empty());
  ASSERT_TRUE(r.run("M486 P1"));
  EXPECT_EQ(r.interp.objects().excluded(), (std::vector<std::string>{"P0"}));
  ASSERT_TRUE(r.run("M486 S0"));
  EXPECT_EQ(r.interp.objects().current(), box);  // the index reaches its name
  ASSERT_TRUE(r.run("G1 X40 Y40 F6000"));
  ASSERT_TRUE(r.run("G1 X60 Y40 E1.0 F1800"));
  ASSERT_TRUE(r.run("M486 S-1"));
  const uint64_t moves_after_0 = r.planner.moves_added();
  ASSERT_TRUE(r.run("M486 S1"));
  ASSERT_TRUE(r.run("G1 X140 Y140 F6000"));
  ASSERT_TRUE(r.run("G1 X160 Y140 E1.0 F1800"));
  ASSERT_TRUE(r.run("M486 S-1"));
  EXPECT_EQ(r.planner.moves_added(), moves_after_0);  // nothing of object 1 moved
  EXPECT_EQ(r.interp.skipped_lines(), 2u);
  EXPECT_DOUBLE_EQ(r.interp.state().machine_mm[kX], 60.0);
  // M486 C inside object 0: the rest of it is skipped; outside any object it is an error.
  ASSERT_TRUE(r.run("M486 S0"));
  ASSERT_TRUE(r.run("G1 X50 Y50 E0.5"));
  ASSERT_TRUE(r.run("M486 C"));
  ASSERT_TRUE(r.run("G1 X70 Y50 E0.5"));
  ASSERT_TRUE(r.run("M486 S-1"));
  EXPECT_DOUBLE_EQ(r.interp.state().machine_mm[kX], 50.0);
  EXPECT_EQ(r.interp.objects().excluded(), (std::vector<std::string>{"P0", box}));
  auto s = r.run("M486 C");
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("no object is being printed"), std::string::npos);
  // A new plate: nothing defined or excluded, no alias.
  ASSERT_TRUE(r.run("M486 T1"));
  EXPECT_TRUE(r.interp.objects().defined().empty());
  EXPECT_TRUE(r.interp.objects().excluded().empty());
  EXPECT_TRUE(r.interp.objects().empty());
  ASSERT_TRUE(r.run("M486 S0"));
  EXPECT_EQ(r.interp.objects().current(), "0");
  EXPECT_FALSE(r.interp.objects().empty());
}

// A named Marlin object is excluded by the name the web shows (Mainsail's "exclude object" sends
// EXCLUDE_OBJECT NAME=<name>) as by its index; RepRapFirmware's one-line form starts and names
// an object; a name another object has leaves the object its index; a stray name is ignored.
TEST(Interpreter, NamedMarlinObjectsAreExcludedByTheirNames) {
  Rig r(test::cartesian_config());
  for (const char* l : {"G28", "M83", "M486 AStray", "M486 T3", "M486 S0", "M486 ACube id:0 copy 0",
                        "M486 S-1", "M486 S1 A\"Bolt copy 1\"", "M486 S-1", "M486 S2",
                        "M486 ACube id:0 copy 0", "M486 S-1", "G1 Z0.3 F600"})
    ASSERT_TRUE(r.run(l)) << l;
  EXPECT_EQ(r.interp.objects().defined(),
            (std::vector<std::string>{"CUBE_ID:0_COPY_0", "BOLT_COPY_1", "2"}));
  ASSERT_TRUE(r.run("EXCLUDE_OBJECT NAME=CUBE_ID:0_COPY_0"));
  ASSERT_TRUE(r.run("M486 P1"));
  EXPECT_EQ(r.interp.objects().excluded(),
            (std::vector<std::string>{"CUBE_ID:0_COPY_0", "BOLT_COPY_1"}));
  const uint64_t before = r.planner.moves_added();
  for (const char* l : {"M486 S0", "G1 X40 Y40 F6000", "G1 X60 Y40 E1.0 F1800", "M486 S-1",
                        "M486 S1", "G1 X140 Y140 F6000", "M486 S-1"})
    ASSERT_TRUE(r.run(l)) << l;
  EXPECT_EQ(r.planner.moves_added(), before);  // both skipped, by either name
  EXPECT_EQ(r.interp.skipped_lines(), 3u);
  ASSERT_TRUE(r.run("M486 S2"));
  ASSERT_TRUE(r.run("G1 X100 Y100 F6000"));
  EXPECT_EQ(r.planner.moves_added(), before + 1);  // object 2 prints
  // An object excluded by its index before it was named stays excluded under its name.
  ASSERT_TRUE(r.run("M486 T1"));
  ASSERT_TRUE(r.run("M486 P0"));
  ASSERT_TRUE(r.run("M486 S0"));
  ASSERT_TRUE(r.run("M486 AGear"));
  EXPECT_EQ(r.interp.objects().excluded(), (std::vector<std::string>{"GEAR"}));
  EXPECT_EQ(r.interp.objects().defined(), (std::vector<std::string>{"GEAR"}));
}

TEST(Interpreter, M204SelectsPrintRetractAndTravelAcceleration) {
  Rig r(test::cartesian_config());
  ASSERT_TRUE(r.run("M204 P1000 R500 T2000"));
  ASSERT_TRUE(r.run("G1 X50 E2 F6000"));  // print move
  ASSERT_TRUE(r.run("G1 E1"));            // retract (E-only)
  ASSERT_TRUE(r.run("G1 X100"));          // travel
  ASSERT_TRUE(r.run("M204 S800"));        // legacy: print and travel
  ASSERT_TRUE(r.run("G1 X120 E2"));
  ASSERT_TRUE(r.run("G1 X140"));
  r.planner.flush();
  ASSERT_EQ(r.rec.moves.size(), 5u);
  EXPECT_DOUBLE_EQ(r.rec.moves[0].accel_mm_s2, 1000.0);
  EXPECT_DOUBLE_EQ(r.rec.moves[1].accel_mm_s2, 500.0);
  EXPECT_FALSE(r.rec.moves[1].kinematic);
  EXPECT_DOUBLE_EQ(r.rec.moves[2].accel_mm_s2, 2000.0);
  EXPECT_DOUBLE_EQ(r.rec.moves[3].accel_mm_s2, 800.0);
  EXPECT_DOUBLE_EQ(r.rec.moves[4].accel_mm_s2, 800.0);
  EXPECT_DOUBLE_EQ(r.interp.state().retract_accel_mm_s2, 500.0);
}

TEST(Interpreter, SpeedAndFlowOverrides) {
  Rig r(test::cartesian_config());
  ASSERT_TRUE(r.run("M220 S50"));
  ASSERT_TRUE(r.run("M221 S90"));
  ASSERT_TRUE(r.run("G1 X200 E10 F6000"));  // 100 mm/s requested -> 50 mm/s
  r.planner.flush();
  ASSERT_EQ(r.rec.moves.size(), 1u);
  EXPECT_NEAR(r.rec.moves[0].v_cruise_mm_s, 50.0, 1e-9);
  EXPECT_NEAR(r.rec.moves[0].end_mm[kE], 9.0, 1e-12);  // flow 90 %
  EXPECT_NEAR(r.interp.state().logical_mm[kE], 10.0, 1e-12);
  EXPECT_FALSE(r.run("M220 S0").ok());
  EXPECT_DOUBLE_EQ(r.interp.state().speed_factor, 0.5);
}

TEST(Interpreter, SpeedOverrideBackupAndRestore) {
  Rig r(test::cartesian_config());
  ASSERT_TRUE(r.run("M220 S80"));
  ASSERT_TRUE(r.run("M220 B S120"));  // backs 80 % up, then sets 120 %
  EXPECT_DOUBLE_EQ(r.interp.state().speed_factor, 1.2);
  ASSERT_TRUE(r.run("G1 X100 F6000"));  // 100 mm/s requested -> 120 mm/s
  ASSERT_TRUE(r.run("M220 R"));
  EXPECT_DOUBLE_EQ(r.interp.state().speed_factor, 0.8);
  ASSERT_TRUE(r.run("G1 X0"));
  r.planner.flush();
  ASSERT_EQ(r.rec.moves.size(), 2u);
  EXPECT_NEAR(r.rec.moves[0].v_cruise_mm_s, 120.0, 1e-9);
  EXPECT_NEAR(r.rec.moves[1].v_cruise_mm_s, 80.0, 1e-9);
  EXPECT_FALSE(r.run("M220 B S0").ok());  // refused whole: the backup is not taken either
  EXPECT_DOUBLE_EQ(r.interp.state().saved_speed_factor, 0.8);
}

TEST(Interpreter, DwellAndWaitAreEvents) {
  Rig r(test::cartesian_config());
  ASSERT_TRUE(r.run("G1 X30 F6000"));
  ASSERT_TRUE(r.run("G4 P500"));
  ASSERT_TRUE(r.run("G1 X60"));
  ASSERT_TRUE(r.run("M400"));
  ASSERT_EQ(r.rec.events.size(), 2u);
  ASSERT_EQ(r.rec.moves.size(), 2u);
  EXPECT_EQ(r.rec.events[0].kind, EventKind::dwell);
  EXPECT_DOUBLE_EQ(r.rec.events[0].duration_s, 0.5);
  EXPECT_DOUBLE_EQ(r.rec.events[0].time_s, r.rec.moves[0].end_time_s());
  EXPECT_DOUBLE_EQ(r.rec.moves[1].start_time_s, r.rec.moves[0].end_time_s() + 0.5);
  EXPECT_EQ(r.rec.events[1].kind, EventKind::moves_done);
  EXPECT_DOUBLE_EQ(r.rec.events[1].time_s, r.rec.moves[1].end_time_s());
  EXPECT_EQ(r.planner.queued(), 0u);
}

TEST(Interpreter, FirmwareRetraction) {
  Rig r(test::cartesian_config());
  ASSERT_TRUE(r.run("M207 S1.5 F2400 Z0.4"));
  ASSERT_TRUE(r.run("M208 S0.1 F1200"));
  ASSERT_TRUE(r.run("G1 X10 Z1 F3000"));
  ASSERT_TRUE(r.run("G10"));
  EXPECT_DOUBLE_EQ(r.interp.state().machine_mm[kE], -1.5);
  EXPECT_DOUBLE_EQ(r.interp.state().machine_mm[kZ], 1.4);
  EXPECT_DOUBLE_EQ(r.interp.state().logical_mm[kZ], 1.0);
  ASSERT_TRUE(r.run("G10"));  // already retracted: nothing
  ASSERT_TRUE(r.run("G11"));
  EXPECT_NEAR(r.interp.state().machine_mm[kE], 0.1, 1e-12);
  EXPECT_DOUBLE_EQ(r.interp.state().machine_mm[kZ], 1.0);
  r.planner.flush();
  ASSERT_EQ(r.rec.moves.size(), 5u);
  EXPECT_NEAR(r.rec.moves[1].v_cruise_mm_s, 40.0, 1e-9) << "retract at F2400";
  EXPECT_NEAR(r.rec.moves[4].v_cruise_mm_s, 20.0, 1e-9) << "recover at F1200";
}

TEST(Interpreter, RejectedMoveChangesNothing) {
  Rig r(test::cartesian_config());
  ASSERT_TRUE(r.run("G1 X10 Y10 F3000"));
  const MachineState before = r.interp.state();
  const uint64_t added = r.planner.moves_added();
  gcode::Command c = *gcode::parse_line("G1 X250 Y10 E3 F1200", {"part.gcode", 42, 0});
  Status s = r.interp.execute(c);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().where.line, 42);
  EXPECT_NE(s.error().to_string().find("part.gcode:42"), std::string::npos);
  EXPECT_NE(s.error().message.find("X250"), std::string::npos) << s.error().message;
  EXPECT_EQ(r.planner.moves_added(), added);
  EXPECT_EQ(r.interp.state().machine_mm, before.machine_mm);
  EXPECT_EQ(r.interp.state().logical_mm, before.logical_mm);
  EXPECT_DOUBLE_EQ(r.interp.state().feedrate_mm_s, before.feedrate_mm_s);  // F not taken either
  // An arc whose ends are on the bed but whose middle is not: no segment of it is queued.
  Status a = r.run("G2 X30 Y10 I10 J0");  // centre (20, 10), r 10: the CW half over the top
  ASSERT_TRUE(a.ok());
  const uint64_t after_arc = r.planner.moves_added();
  Status b = r.run("G2 X30 Y10 I-15 J0");  // full circle around (15, 10), r 15: dips to y = -5
  ASSERT_FALSE(b.ok());
  EXPECT_NE(b.error().message.find("Y-"), std::string::npos) << b.error().message;
  EXPECT_EQ(r.planner.moves_added(), after_arc);
  EXPECT_DOUBLE_EQ(r.interp.state().machine_mm[kX], 30.0);
}

TEST(Interpreter, DeltaRejectsUnreachableMoveWhole) {
  Rig r(test::delta_config());
  ASSERT_TRUE(r.run("G28"));
  ASSERT_TRUE(r.run("G1 X0 Y0 Z10 F6000"));
  const uint64_t added = r.planner.moves_added();
  Status s = r.run("G1 X100 Y100 Z10");  // radius 141 > 135
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("print radius"), std::string::npos) << s.error().message;
  EXPECT_EQ(r.planner.moves_added(), added);
  r.planner.flush();
  for (const PlannedMove& m : r.rec.moves) {
    EXPECT_LE(std::hypot(m.end_mm[0], m.end_mm[1]), 135.0);
  }
}

// Arc points lie on the circle and every chord stays within the tolerance of it.
void check_arc(Rig& r, const std::string& line, double cx, double cy, double radius, double tol, double sweep_rad) {
  r.planner.flush();
  const size_t first = r.rec.moves.size();
  ASSERT_TRUE(r.run(line)) << line;
  r.planner.flush();
  double max_sagitta = 0.0, swept = 0.0;
  for (size_t i = first; i < r.rec.moves.size(); ++i) {
    const PlannedMove& m = r.rec.moves[i];
    const double re = std::hypot(m.end_mm[0] - cx, m.end_mm[1] - cy);
    EXPECT_NEAR(re, radius, 1e-9);
    const double mx = 0.5 * (m.start_mm[0] + m.end_mm[0]) - cx, my = 0.5 * (m.start_mm[1] + m.end_mm[1]) - cy;
    max_sagitta = std::max(max_sagitta, radius - std::hypot(mx, my));
    const double a0 = std::atan2(m.start_mm[1] - cy, m.start_mm[0] - cx), a1 = std::atan2(m.end_mm[1] - cy, m.end_mm[0] - cx);
    swept += std::remainder(a1 - a0, 2.0 * M_PI);
  }
  EXPECT_LE(max_sagitta, tol * (1.0 + 1e-9));
  EXPECT_GT(max_sagitta, 0.5 * tol) << "segments should not be needlessly short";
  EXPECT_NEAR(swept, sweep_rad, 1e-9);
}

TEST(Interpreter, ArcsStayWithinChordalTolerance) {
  PlannerConfig c = test::cartesian_config();
  c.arc_tolerance_mm = 0.005;
  Rig r(c);
  ASSERT_TRUE(r.run("G1 X100 Y50 F6000"));
  check_arc(r, "G3 X100 Y50 I0 J20 E5", 100.0, 70.0, 20.0, 0.005, 2.0 * M_PI);  // full circle CCW
  check_arc(r, "G2 X120 Y70 I0 J20", 100.0, 70.0, 20.0, 0.005, -1.5 * M_PI);      // CW three quarters
  check_arc(r, "G2 X140 Y70 R10", 130.0, 70.0, 10.0, 0.005, -M_PI);              // R: half circle
  check_arc(r, "G3 X150 Y80 R-10", 150.0, 70.0, 10.0, 0.005, 1.5 * M_PI);        // R < 0: the long way
  // E of the full circle rose linearly with the angle: constant E per mm on every segment
  EXPECT_FALSE(r.run("G2 X200 Y70 R5").ok());  // R smaller than half the chord
}

TEST(Interpreter, M205SetsJunctionDeviationAndRecordsJerk) {
  Rig r(test::cartesian_config());
  ASSERT_TRUE(r.run("M205 X8 Y8 Z0.4 E4.5 J0.02"));
  EXPECT_DOUBLE_EQ(r.planner.junction_deviation(), 0.02);
  EXPECT_DOUBLE_EQ(r.interp.state().jerk_mm_s[kX], 8.0);
  EXPECT_DOUBLE_EQ(r.interp.state().jerk_mm_s[kE], 4.5);
}

// Klipper's extrusion bounds: an E-only move over max_extrude_only_distance and a move that
// would lay a track wider than max_extrude_cross_section are refused whole (the G-code position
// and the planner unchanged; "G1 X1e999" reads as X1 E999, which a cross-section catches); a tiny
// amount over the section passes, retraction is not bounded by it, and 0 turns either off.
TEST(Interpreter, ExtrusionBeyondKlippersBoundsIsRefusedWhole) {
  PlannerConfig cfg = test::cartesian_config();
  Rig r(cfg);
  ASSERT_TRUE(r.run("G28"));
  ASSERT_TRUE(r.run("G1 X10 E1 F3000"));
  const uint64_t moves = r.planner.moves_added();
  const Vec4 at = r.interp.state().machine_mm;
  Status s = r.run("G1 X1e999");  // parsed as X1 E999: the exponent is a parameter
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("move exceeds maximum extrusion"), std::string::npos)
      << s.error().message;
  s = r.run("G1 E61");  // 60 mm of E alone
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("extrude-only move too long (60.000 mm vs 50.000 mm"),
            std::string::npos)
      << s.error().message;
  ASSERT_FALSE(r.run("G1 E-59").ok());  // retracting 60 mm at once too
  EXPECT_EQ(r.planner.moves_added(), moves);
  EXPECT_EQ(r.interp.state().machine_mm, at);
  EXPECT_EQ(r.interp.state().logical_mm[kE], 1.0);
  // 0.6 mm^2 of track (under 0.64) passes, 0.7 does not; 0.1 mm of E over 0.1 mm of travel is a
  // tiny amount (under 0.4 mm of a 0.64 mm^2 track) and passes.
  const double area_mm2 = std::numbers::pi / 4.0 * 1.75 * 1.75;
  char line[64];
  std::snprintf(line, sizeof line, "G1 X20 E%.6f", 1.0 + 0.6 * 10.0 / area_mm2);
  EXPECT_TRUE(r.run(line).ok());
  std::snprintf(line, sizeof line, "G1 X30 E%.6f", 1.0 + (0.6 + 0.7) * 10.0 / area_mm2);
  EXPECT_FALSE(r.run(line).ok());
  ASSERT_TRUE(r.run("G92 E0"));
  EXPECT_TRUE(r.run("G1 X20.1 E0.1").ok());
  EXPECT_TRUE(r.run("G1 E50").ok());  // a filament load of 49.9 mm
  EXPECT_TRUE(r.run("G10").ok());     // firmware retraction (3 mm) and back
  EXPECT_TRUE(r.run("G11").ok());
  // Both bounds off.
  cfg.max_extrude_only_distance_mm = 0.0;
  cfg.max_extrude_cross_section_mm2 = 0.0;
  Rig off(cfg);
  ASSERT_TRUE(off.run("G28"));
  EXPECT_TRUE(off.run("G1 E500").ok());
  EXPECT_TRUE(off.run("G1 X1 E999").ok());
}

// The machine's extrude guard (a cold hotend, engine::Machine) is asked before every move that
// moves E, and only then: its refusal leaves everything as it was, its reason in the error.
TEST(Interpreter, TheExtrudeGuardRefusesEveryEMoveAndOnlyThose) {
  Rig r(test::cartesian_config());
  int asked = 0;
  std::string why = "Extrude below minimum temp: cold";
  r.interp.set_extrude_guard([&] {
    ++asked;
    return why;
  });
  ASSERT_TRUE(r.run("G28"));
  ASSERT_TRUE(r.run("G1 X10 F3000"));
  ASSERT_TRUE(r.run("G92 E5"));
  EXPECT_EQ(asked, 0);
  const uint64_t moves = r.planner.moves_added();
  for (const char* l : {"G1 X20 E6", "G1 E4", "G2 X20 Y0 I5 J0 E7", "G10"}) {
    Status s = r.run(l);
    ASSERT_FALSE(s.ok()) << l;
    EXPECT_NE(s.error().message.find("move rejected, nothing executed: Extrude below minimum temp"),
              std::string::npos)
        << s.error().message;
  }
  EXPECT_EQ(asked, 4);
  EXPECT_EQ(r.planner.moves_added(), moves);
  EXPECT_EQ(r.interp.state().logical_mm[kE], 5.0);
  EXPECT_FALSE(r.interp.state().retracted);
  EXPECT_TRUE(r.run("G1 X20 E5").ok());  // E unchanged: not asked
  EXPECT_EQ(asked, 4);
  why.clear();
  EXPECT_TRUE(r.run("G1 X30 E6").ok());
  EXPECT_EQ(asked, 5);
}

}  // namespace
}  // namespace feedloop::planner
