// Smoothed pressure advance (planner/pressure_advance.hpp): the closed form against the definition
// integrated numerically, the advance K v on steady extrusion, none on retracts, the exact return
// to rest, the Hermite output; M900 / SET_PRESSURE_ADVANCE through the parser and interpreter.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "gcode/parser.hpp"
#include "planner/interpreter.hpp"
#include "planner/kinematics.hpp"
#include "planner/lookahead.hpp"
#include "planner/pressure_advance.hpp"
#include "planner/sampler.hpp"
#include "planner_test_util.hpp"

namespace feedloop::planner {
namespace {

struct Moves final : MoveSink {
  std::vector<PlannedMove> v;
  void on_move(const PlannedMove& m) override { v.push_back(m); }
};

// Plans `program` (one command per line) with the cart220 limits.
std::vector<PlannedMove> plan(const std::string& program, double k_s = 0.0,
                              double smooth_s = 0.04) {
  PlannerConfig cfg = test::cartesian_config();
  cfg.pressure_advance_s = k_s;
  cfg.pressure_advance_smooth_time_s = smooth_s;
  Moves sink;
  const auto kin = make_kinematics(cfg);
  Planner planner(cfg, sink);
  Interpreter interp(cfg, *kin, planner);
  size_t pos = 0;
  int line = 0;
  while (pos < program.size()) {
    const size_t nl = program.find('\n', pos);
    const std::string text =
        program.substr(pos, nl == std::string::npos ? std::string::npos : nl - pos);
    pos = nl == std::string::npos ? program.size() : nl + 1;
    auto cmd = gcode::parse_line(text, SourceLocation{"t.gcode", ++line, 0});
    EXPECT_TRUE(cmd.ok()) << text;
    if (cmd.ok() && !cmd.value().empty()) {
      EXPECT_TRUE(interp.execute(cmd.value())) << text;
    }
  }
  planner.flush();
  return sink.v;
}

// Nominal e(t) and f(t) = e + K e' (K only on extruding XY moves), rest outside the moves.
double f_of(const std::vector<PlannedMove>& moves, double t, double k_s) {
  for (size_t i = 0; i < moves.size(); ++i) {
    const PlannedMove& m = moves[i];
    if (t >= m.start_time_s && t < m.end_time_s()) {
      const CartesianSample c = sample_move(m, t);
      return c.pos_mm[kE] + (pressure_advance_applies(m) ? k_s : 0.0) * c.vel_mm_s[kE];
    }
    if (t < m.start_time_s) return i == 0 ? m.start_mm[kE] : moves[i - 1].end_mm[kE];
  }
  return moves.back().end_mm[kE];
}

// The definition, by the midpoint rule on a fine grid.
double e_adv_numeric(const std::vector<PlannedMove>& moves, double t, double k_s, double h) {
  const int n = 20000;
  double sum = 0.0;
  for (int i = 0; i < n; ++i) {
    const double s = -h + (i + 0.5) * (2.0 * h / n);
    sum += f_of(moves, t + s, k_s) * (h - std::abs(s)) / (h * h) * (2.0 * h / n);
  }
  return sum;
}

const char* kSquare =
    "G1 X10 Y10 F6000\n"
    "G1 X60 Y10 E2.5 F3000\n"
    "G1 X60 Y60 E5.0\n"
    "G1 E4.2 F2400\n"     // retract (E only)
    "G1 X10 Y60 F9000\n"  // travel
    "G1 E5.0 F2400\n"     // unretract
    "G1 X10 Y10 E7.5 F1800\n";

TEST(PressureAdvance, ClosedFormMatchesTheDefinitionAcrossCornersAndRetracts) {
  const double k = 0.05, smooth = 0.04, h = 0.5 * smooth;
  auto moves = plan(kSquare, k, smooth);
  ASSERT_GE(moves.size(), 6u);
  PressureAdvance pa;
  pa.restart(moves.front().start_mm[kE], smooth);
  for (const PlannedMove& m : moves) pa.push(m);
  EXPECT_DOUBLE_EQ(pa.half_window_s(), h);
  int checked = 0;
  const double t_end = moves.back().end_time_s() + 2 * h;
  for (double t = moves.front().start_time_s - h; t < t_end; t += 0.0173) {
    const double ref = e_adv_numeric(moves, t, k, h);
    EXPECT_NEAR(pa.position_mm(t), ref, 2e-6) << "t = " << t;
    // The derivative against a central difference of the closed form.
    const double d = 1e-6;
    const double num_v = (pa.position_mm(t + d) - pa.position_mm(t - d)) / (2 * d);
    EXPECT_NEAR(pa.velocity_mm_s(t), num_v, 1e-3 + 1e-4 * std::abs(num_v)) << "t = " << t;
    ++checked;
  }
  EXPECT_GT(checked, 50);
}

TEST(PressureAdvance, SteadyExtrusionIsAdvancedByKTimesTheVelocityRetractsAreNot) {
  const double k = 0.08, smooth = 0.04;
  // A long cruise: 200 mm at 50 mm/s with 0.05 mm of filament per mm (2.5 mm/s of filament).
  auto moves = plan("G1 X10 Y10 F6000\nG1 X210 Y10 E10 F3000\nG1 E0 F600\n", k, smooth);
  ASSERT_EQ(moves.size(), 3u);
  PressureAdvance pa;
  pa.restart(0.0, smooth);
  for (const PlannedMove& m : moves) pa.push(m);
  const PlannedMove& cruise = moves[1];
  const double t_mid = cruise.start_time_s + 0.5 * cruise.duration_s;
  const CartesianSample c = sample_move(cruise, t_mid);
  ASSERT_NEAR(c.vel_mm_s[kE], 2.5, 1e-9);
  EXPECT_NEAR(pa.position_mm(t_mid) - c.pos_mm[kE], k * 2.5, 1e-9);  // e + K v
  EXPECT_NEAR(pa.velocity_mm_s(t_mid), 2.5, 1e-9);
  // The retract (E only, 10 mm at 10 mm/s) gets no advance: e_adv = e in its cruise.
  const PlannedMove& retract = moves[2];
  ASSERT_FALSE(pressure_advance_applies(retract));
  const double t_r = retract.start_time_s + 0.5 * retract.duration_s;
  EXPECT_NEAR(pa.position_mm(t_r), sample_move(retract, t_r).pos_mm[kE], 1e-9);
  // At rest once the window has passed: exactly the end (the step count is unchanged).
  EXPECT_EQ(pa.position_mm(retract.end_time_s() + 0.5 * smooth + 1e-6), retract.end_mm[kE]);
  EXPECT_EQ(pa.velocity_mm_s(retract.end_time_s() + 0.5 * smooth + 1e-6), 0.0);
}

TEST(PressureAdvance, VelocityIsEdotPlusKTimesEddotAndStaysBounded) {
  // From rest at 500 mm/s^2 to 50 mm/s: f = e + K de/dt is continuous, f' = de/dt + K d2e/dt2 jumps
  // by K u_E a where the acceleration starts and ends; the triangle keeps linear pieces (inside a
  // phase, farther than h from its ends, de_adv/dt = u_E (v + K a)) and averages the jumps.
  const double k = 0.1, smooth = 0.04, h = 0.02, a = 500.0;
  auto moves = plan("M204 P500\nG1 X110 Y10 E5 F3000\n", k, smooth);
  ASSERT_EQ(moves.size(), 1u);
  const PlannedMove& m = moves[0];
  const double u_e = m.unit[kE];
  ASSERT_NEAR(m.accel_t_s, 0.1, 1e-9);
  PressureAdvance pa;
  pa.restart(0.0, smooth);
  pa.push(m);
  const double t_in = m.start_time_s + 0.05;  // mid-acceleration: v = 25 mm/s
  EXPECT_NEAR(pa.velocity_mm_s(t_in), u_e * (a * 0.05 + k * a), 1e-9);
  double vmax = 0.0;
  for (double t = m.start_time_s - h; t < m.end_time_s() + h; t += 1e-4)
    vmax = std::max(vmax, std::abs(pa.velocity_mm_s(t)));
  EXPECT_LE(vmax, u_e * (50.0 + k * a) + 1e-9);
  EXPECT_GT(vmax, 0.85 * u_e * (50.0 + k * a));
}

TEST(PressureAdvance, HermiteOutputIsContinuousExactAtKnotsAndEndsAtRest) {
  const double k = 0.05, smooth = 0.04, h = 0.02, period = 0.001;
  auto moves = plan(kSquare, k, smooth);
  PressureAdvance pa;
  pa.restart(moves.front().start_mm[kE], smooth);
  for (const PlannedMove& m : moves) pa.push(m);
  pa.set_emitted_from(moves.front().start_time_s - h);
  std::vector<JointSegment> segs;
  const double end = moves.back().end_time_s() + h + 0.5;
  // In chunks, as the servo cycles call it.
  for (double until = moves.front().start_time_s; until < end + 0.01; until += 0.0037)
    pa.emit_until(std::min(until, end), period, [&](const JointSegment& s) { segs.push_back(s); });
  ASSERT_GT(segs.size(), 100u);
  double max_gap = 0.0, max_jump = 0.0, max_err = 0.0;
  for (size_t i = 0; i < segs.size(); ++i) {
    const JointSegment& s = segs[i];
    EXPECT_GT(s.duration_s, 0.0);
    if (i > 0) {
      max_gap = std::max(max_gap, std::abs(s.t0_s - segs[i - 1].end_s()));
      max_jump =
          std::max(max_jump, std::abs(s.c0_mm - segs[i - 1].position_mm(segs[i - 1].end_s())));
    }
    const double tm = s.t0_s + 0.5 * s.duration_s;
    max_err = std::max(max_err, std::abs(s.position_mm(tm) - pa.position_mm(tm)));
  }
  EXPECT_LT(max_gap, 1e-12);
  EXPECT_LT(max_jump, 1e-9);
  EXPECT_LT(max_err, 1e-6);  // interpolation error mid-piece
  EXPECT_EQ(segs.back().position_mm(segs.back().end_s()), moves.back().end_mm[kE]);
  EXPECT_NEAR(segs.back().end_s(), end, 1e-9);
}

TEST(PressureAdvance, M900AndSetPressureAdvanceSetTheValuesBadValuesChangeNothing) {
  PlannerConfig cfg = test::cartesian_config();
  Moves sink;
  const auto kin = make_kinematics(cfg);
  Planner planner(cfg, sink);
  Interpreter interp(cfg, *kin, planner);
  auto run = [&](const char* line) -> Status {
    auto cmd = gcode::parse_line(line, SourceLocation{"t.gcode", 7, 0});
    if (!cmd.ok()) return cmd.error();
    return interp.execute(cmd.value());
  };
  EXPECT_DOUBLE_EQ(interp.state().pressure_advance_s, 0.0);
  EXPECT_DOUBLE_EQ(interp.state().pressure_advance_smooth_time_s, 0.04);
  ASSERT_TRUE(run("M900 K0.06"));
  EXPECT_DOUBLE_EQ(interp.state().pressure_advance_s, 0.06);
  ASSERT_TRUE(run("set_pressure_advance advance=0.125 SMOOTH_TIME=0.03 EXTRUDER=extruder"));
  EXPECT_DOUBLE_EQ(interp.state().pressure_advance_s, 0.125);
  EXPECT_DOUBLE_EQ(interp.state().pressure_advance_smooth_time_s, 0.03);
  // Refused, located, nothing changed.
  Status st = run("M900 K11");
  ASSERT_FALSE(st);
  EXPECT_EQ(st.error().where.line, 7);
  EXPECT_NE(st.error().message.find("K"), std::string::npos) << st.error().message;
  st = run("SET_PRESSURE_ADVANCE SMOOTH_TIME=0.5");
  ASSERT_FALSE(st);
  EXPECT_NE(st.error().message.find("SMOOTH_TIME must be in (0, 0.200]"), std::string::npos)
      << st.error().message;
  st = run("SET_PRESSURE_ADVANCE ADVANCE=-1");
  ASSERT_FALSE(st);
  st = run("SET_PRESSURE_ADVANCE ADVANCE=0.2 SMOOTH_TIME=0");  // one bad value: neither applies
  ASSERT_FALSE(st);
  st = run("SET_PRESSURE_ADVANCE ADVANCE=abc");
  ASSERT_FALSE(st);
  EXPECT_EQ(st.error().where.column, 30) << st.error().message;  // at the value
  st = run("SET_PRESSURE_ADVANCE FOO=1");
  ASSERT_FALSE(st);
  EXPECT_NE(st.error().message.find("unknown parameter FOO"), std::string::npos)
      << st.error().message;
  st = run("SET_PRESSURE_ADVANCE EXTRUDER=extruder1 ADVANCE=0.1");
  ASSERT_FALSE(st);
  EXPECT_DOUBLE_EQ(interp.state().pressure_advance_s, 0.125);
  EXPECT_DOUBLE_EQ(interp.state().pressure_advance_smooth_time_s, 0.03);
  // The values travel with the moves queued after them.
  ASSERT_TRUE(run("G1 X20 Y20 E1 F3000"));
  ASSERT_TRUE(run("M900 K0"));
  ASSERT_TRUE(run("G1 X30 Y20 E2"));
  planner.flush();
  ASSERT_EQ(sink.v.size(), 2u);
  EXPECT_DOUBLE_EQ(sink.v[0].pressure_advance_s, 0.125);
  EXPECT_DOUBLE_EQ(sink.v[0].pressure_advance_smooth_time_s, 0.03);
  EXPECT_DOUBLE_EQ(sink.v[1].pressure_advance_s, 0.0);
}

}  // namespace
}  // namespace feedloop::planner
