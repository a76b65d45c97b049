// Lookahead hand cases: junction deviation and square corner velocity, the sharp-corner speed
// assignment (Eq. 63-69), minimum cruise ratio, S-curve jerk bound, bounded window and the
// ability to stop at the end of the queue.
#include <gtest/gtest.h>

#include <cmath>

#include "planner/junction.hpp"
#include "planner/profile.hpp"
#include "planner_test_util.hpp"

namespace feedloop::planner {
namespace {

struct Collect : MoveSink {
  std::vector<PlannedMove> moves;
  void on_move(const PlannedMove& m) override { moves.push_back(m); }
};

std::vector<PlannedMove> plan(const PlannerConfig& c, const std::vector<Vec4>& points, double v, double a) {
  Collect sink;
  Planner p(c, sink);
  p.set_position(points[0]);
  for (size_t i = 1; i < points.size(); ++i) p.add_move({points[i], v, a, static_cast<int>(i)});
  p.flush();
  return sink.moves;
}

TEST(Lookahead, NinetyDegreeCornerAtSquareCornerVelocity) {
  PlannerConfig c = test::cartesian_config();
  c.square_corner_velocity_mm_s = 5.0;
  const auto m = plan(c, {{0, 0, 0, 0}, {100, 0, 0, 0}, {100, 100, 0, 0}}, 200.0, 3000.0);
  ASSERT_EQ(m.size(), 2u);
  EXPECT_NEAR(m[0].v_exit_mm_s, 5.0, 1e-9);  // Klipper: a 90-degree corner at scv
  EXPECT_NEAR(m[1].v_entry_mm_s, 5.0, 1e-9);
  EXPECT_NEAR(m[0].v_cruise_mm_s, 200.0, 1e-9);
  EXPECT_DOUBLE_EQ(m[1].v_exit_mm_s, 0.0);
}

TEST(Lookahead, JunctionSpeedFollowsTheDeviationFormula) {
  PlannerConfig c = test::cartesian_config();
  c.junction_deviation_mm = 0.05;  // Marlin-style explicit value
  for (double deg : {10.0, 30.0, 60.0, 90.0, 135.0, 170.0}) {
    const double th = deg * M_PI / 180.0;
    const auto m = plan(c, {{10, 10, 0, 0}, {110, 10, 0, 0}, {110 + 50 * std::cos(th), 10 + 50 * std::sin(th), 0, 0}}, 250.0, 2000.0);
    ASSERT_EQ(m.size(), 2u);
    // theta of the formula is the angle between the reversed incoming and the outgoing direction
    const double theta = M_PI - th;
    const double sin_d2 = std::sin(theta / 2.0);
    const double v2_jd = sin_d2 / (1.0 - sin_d2) * 0.05 * 2000.0;
    const double v2_cent = 2.0 * 2000.0 * 50.0 * 0.25 * std::tan(theta / 2.0);  // shorter move
    const double expect = std::sqrt(std::min({v2_jd, v2_cent, 250.0 * 250.0}));
    EXPECT_NEAR(m[0].v_exit_mm_s, expect, 1e-9 * (1 + expect)) << deg << " deg";
  }
}

TEST(SharpCorner, FormulaHandCases) {
  const SharpCornerParams p;  // Table II: alpha_a 5, alpha_b 20, a1 0.05, a2 0.005
  // Eq. 68 by hand: h(0) = 1/2 - atan(10)/pi, h(1/2) = 1/2 + atan(90)/pi
  EXPECT_NEAR(sharp_corner_h(0.0, p), 0.0317255174, 1e-9);
  EXPECT_NEAR(sharp_corner_h(0.5, p), 0.99646337, 1e-8);
  EXPECT_DOUBLE_EQ(sharp_corner_k(3.0, p), 0.0);    // non-sharp
  EXPECT_DOUBLE_EQ(sharp_corner_k(12.5, p), 0.5);   // sharp
  EXPECT_DOUBLE_EQ(sharp_corner_k(90.0, p), 1.0);   // very sharp
  EXPECT_NEAR(sharp_corner_speed(100.0, 90.0, p), 3.17255174, 1e-7);
  EXPECT_NEAR(sharp_corner_speed(100.0, 12.5, p), 50.0 * (0.0317255174 + 0.99646337), 1e-6);
  EXPECT_NEAR(sharp_corner_speed(100.0, 0.0, p), 99.646337, 1e-6);
  const double a[3] = {1, 0, 0}, b[3] = {0, 1, 0};
  EXPECT_NEAR(corner_angle_deg(a, b), 90.0, 1e-12);  // Eq. 64
}

TEST(SharpCorner, PlannerUsesEq67AtJunctions) {
  PlannerConfig c = test::cartesian_config();
  c.cornering = CorneringPolicy::sharp_corner;
  const double v = 100.0;
  for (double deg : {3.0, 12.5, 16.0, 45.0, 90.0}) {
    const double th = deg * M_PI / 180.0;
    // long moves so that acceleration does not bind at the corner
    const auto m = plan(c, {{10, 10, 0, 0}, {110, 10, 0, 0}, {110 + 100 * std::cos(th), 10 + 100 * std::sin(th), 0, 0}}, v, 3000.0);
    ASSERT_EQ(m.size(), 2u);
    const double k = deg < 5.0 ? 0.0 : deg > 20.0 ? 1.0 : (deg - 5.0) / 15.0;  // Eq. 66 by hand
    const double h0 = 0.5 + std::atan(-10.0) / M_PI, hh = 0.5 + std::atan(90.0) / M_PI;
    EXPECT_NEAR(m[0].v_exit_mm_s, v * (k * h0 + (1 - k) * hh), 1e-9) << deg << " deg";
    EXPECT_NEAR(m[1].v_entry_mm_s, m[0].v_exit_mm_s, 1e-12);
  }
}

TEST(Lookahead, MinimumCruiseRatioLimitsShortAccelDecelMoves) {
  PlannerConfig c = test::cartesian_config();
  c.min_cruise_ratio = 0.5;
  // one 10 mm move from rest to rest at a = 1000: without the ratio it would peak at sqrt(a L) = 100
  const auto m = plan(c, {{0, 0, 0, 0}, {10, 0, 0, 0}}, 300.0, 1000.0);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_NEAR(m[0].v_cruise_mm_s, std::sqrt(0.5 * 1000.0 * 10.0), 1e-9);  // accel to decel = a (1 - 0.5)
  EXPECT_NEAR(m[0].cruise_t_s * m[0].v_cruise_mm_s, 5.0, 1e-9);          // half the move cruises
  c.min_cruise_ratio = 0.0;
  const auto n = plan(c, {{0, 0, 0, 0}, {10, 0, 0, 0}}, 300.0, 1000.0);
  EXPECT_NEAR(n[0].v_cruise_mm_s, 100.0, 1e-9);
}

TEST(Lookahead, SCurveKeepsTheJerkAndAccelBounds) {
  PlannerConfig c = test::cartesian_config();
  c.profile = ProfileShape::scurve;
  c.max_jerk_mm_s3 = 1.0e5;
  const auto m = plan(c, {{0, 0, 0, 0}, {150, 0, 0, 0}, {150, 150, 0, 0}, {150, 152, 0, 0}}, 250.0, 3000.0);
  ASSERT_EQ(m.size(), 3u);
  int bounded_moves = 0;
  for (const PlannedMove& mv : m) {
    EXPECT_NEAR(mv.pieces[mv.piece_count - 1].distance_mm(mv.pieces[mv.piece_count - 1].duration_s), mv.length_mm, 1e-9);
    EXPECT_NEAR(mv.pieces[mv.piece_count - 1].velocity_mm_s(mv.pieces[mv.piece_count - 1].duration_s), mv.v_exit_mm_s, 1e-9);
    double t_sum = 0.0;
    for (int k = 0; k < mv.piece_count; ++k) {
      const ProfilePiece& p = mv.pieces[k];
      t_sum += p.duration_s;
      EXPECT_LE(std::abs(p.a0_mm_s2), 3000.0 * (1 + 1e-12));
      EXPECT_LE(std::abs(p.accel_mm_s2(p.duration_s)), 3000.0 * (1 + 1e-12));
      EXPECT_NEAR(p.velocity_mm_s(0.0), p.v0_mm_s, 0.0);
      if (k > 0) {  // continuity of s, v and a between pieces
        const ProfilePiece& q = mv.pieces[k - 1];
        EXPECT_NEAR(q.distance_mm(q.duration_s), p.s0_mm, 1e-9);
        EXPECT_NEAR(q.velocity_mm_s(q.duration_s), p.v0_mm_s, 1e-9);
        EXPECT_NEAR(q.accel_mm_s2(q.duration_s), p.a0_mm_s2, 1e-6);
      }
    }
    EXPECT_NEAR(t_sum, mv.duration_s, 1e-12);
    if (mv.jerk_bounded) {
      ++bounded_moves;
      for (int k = 0; k < mv.piece_count; ++k) EXPECT_LE(std::abs(mv.pieces[k].jerk_mm_s3), c.max_jerk_mm_s3 * (1 + 1e-9));
    }
  }
  EXPECT_EQ(bounded_moves, 3);
}

TEST(Lookahead, WindowIsBoundedAndTheQueueCanAlwaysStop) {
  PlannerConfig c = test::cartesian_config();
  c.lookahead_moves = 8;
  test::Recorder rec;
  Planner p(c, rec);
  rec.planner = &p;
  std::vector<double> dv2;  // 2 a L of every added move, by index
  Vec4 pos{100, 100, 0, 0};
  p.set_position(pos);
  for (int i = 0; i < 400; ++i) {
    const double ang = 0.3 * i;  // a polygon spiral of short segments
    const double len = 0.5 + 0.02 * (i % 50);
    pos = {pos[0] + len * std::cos(ang), pos[1] + len * std::sin(ang), 0.0, pos[3] + 0.01 * len};
    p.add_move({pos, 200.0, 2500.0, i});
    dv2.push_back(2.0 * 2500.0 * len);
    EXPECT_LE(p.queued(), 8u);
  }
  p.flush();
  ASSERT_EQ(rec.moves.size(), 400u);
  for (size_t i = 0; i < rec.moves.size(); ++i) {
    const PlannedMove& m = rec.moves[i];
    EXPECT_EQ(m.index, i);
    if (i + 1 < rec.moves.size()) {
      EXPECT_NEAR(m.v_exit_mm_s, rec.moves[i + 1].v_entry_mm_s, 1e-9);
    }
    // when this move became final, the moves queued behind it sufficed to stop
    double room = 0.0;
    for (uint64_t k = i + 1; k < rec.added_at_emit[i]; ++k) room += dv2[k];
    EXPECT_LE(m.v_exit_mm_s * m.v_exit_mm_s, room * (1 + 1e-9) + 1e-9) << "move " << i;
  }
  EXPECT_DOUBLE_EQ(rec.moves.back().v_exit_mm_s, 0.0);
}

}  // namespace
}  // namespace feedloop::planner

#include "planner/scurve.hpp"

namespace feedloop::planner {
namespace {

TEST(SCurveMath, ReachInvertsDistanceAndPeakFillsTheMove) {
  const double A = 3000.0, J = 1.0e5;  // A^2 / J = 90 mm/s: both regimes below
  for (double v_lo : {0.0, 5.0, 40.0, 150.0}) {
    for (double L : {0.01, 0.3, 2.0, 20.0, 200.0}) {
      const double v_hi = scurve_reach(v_lo, L, A, J);
      EXPECT_NEAR(scurve_distance(v_lo, v_hi, A, J), L, 1e-9 * (1 + L)) << v_lo << " " << L;
      // by hand for the triangular regime: T = 2 sqrt(dv / J)
      const double dv = v_hi - v_lo;
      if (dv < A * A / J) {
        EXPECT_NEAR(scurve_min_time(dv, A, J), 2.0 * std::sqrt(dv / J), 1e-15);
      } else {
        EXPECT_NEAR(scurve_min_time(dv, A, J), dv / A + A / J, 1e-15);
      }
      const double vc = scurve_peak(v_lo, 0.5 * v_lo, L, A, J);
      EXPECT_GE(vc, v_lo);
      if (vc > v_lo + 1e-6) {
        EXPECT_NEAR(scurve_distance(v_lo, vc, A, J) + scurve_distance(0.5 * v_lo, vc, A, J), L, 1e-6 * (1 + L));
      }
    }
  }
}

}  // namespace
}  // namespace feedloop::planner
