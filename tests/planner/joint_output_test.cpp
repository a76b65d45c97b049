// Joint output: cartesian/corexy segments reproduce the exact joint motion; delta cubic Hermite
// pieces per servo period stay within a measured bound of the exact inverse kinematics; the
// sampler and the timeline agree with the moves.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "planner/joint_output.hpp"
#include "planner/sampler.hpp"
#include "planner_test_util.hpp"

namespace feedloop::planner {
namespace {

struct Segments : JointSink {
  std::vector<JointSegment> seg[kJoints];
  void on_joint_segment(int j, const JointSegment& s) override { seg[j].push_back(s); }
};

// Plans a polygonal circle (radius r, n sides) with extrusion and returns the moves.
std::vector<PlannedMove> circle(const PlannerConfig& c, double cx, double cy, double z, double r, int n) {
  test::Recorder rec;
  Planner p(c, rec);
  p.set_position({cx + r, cy, z, 0.0});
  for (int i = 1; i <= n; ++i) {
    const double a = 2.0 * M_PI * i / n;
    p.add_move({{cx + r * std::cos(a), cy + r * std::sin(a), z + 0.01 * i, 0.05 * i}, 150.0, 3000.0, i});
  }
  p.flush();
  return rec.moves;
}

double max_deviation(const Kinematics& kin, const std::vector<PlannedMove>& moves, const Segments& s, double* max_len_s) {
  double worst = 0.0;
  *max_len_s = 0.0;
  size_t mi = 0;
  for (int j = 0; j < kJoints; ++j) {
    mi = 0;
    double prev_end = moves.front().start_time_s;
    for (const JointSegment& g : s.seg[j]) {
      EXPECT_NEAR(g.t0_s, prev_end, 1e-9) << "joint " << j << " segments are contiguous";
      prev_end = g.end_s();
      if (j < 3) *max_len_s = std::max(*max_len_s, g.duration_s);
      for (double f : {0.0, 0.25, 0.5, 0.75, 1.0}) {
        const double t = g.t0_s + f * g.duration_s;
        while (mi + 1 < moves.size() && t > moves[mi].end_time_s()) ++mi;
        double exact;
        if (j < 3) {
          exact = sample_joints(kin, moves[mi], t)[j];
        } else {
          exact = sample_move(moves[mi], t).pos_mm[kE];
        }
        worst = std::max(worst, std::abs(g.position_mm(t) - exact));
      }
    }
  }
  return worst;
}

TEST(JointOutput, LinearKinematicsSegmentsAreExact) {
  for (KinematicsKind kind : {KinematicsKind::cartesian, KinematicsKind::corexy}) {
    PlannerConfig c = test::cartesian_config();
    c.kinematics = kind;
    auto kin = make_kinematics(c);
    const auto moves = circle(c, 110.0, 110.0, 1.0, 40.0, 60);
    Segments s;
    JointEmitter em(*kin, c.servo_period_s);
    for (const PlannedMove& m : moves) em.emit(m, s);
    double max_len = 0.0;
    const double dev = max_deviation(*kin, moves, s, &max_len);
    EXPECT_LT(dev, 1e-9);
    EXPECT_EQ(s.seg[0].size(), s.seg[3].size());
    for (const JointSegment& g : s.seg[0]) EXPECT_EQ(g.c3_mm_s3, 0.0);  // trapezoid: quadratic
  }
}

TEST(JointOutput, DeltaHermitePiecesTrackExactInverseKinematics) {
  PlannerConfig c = test::delta_config();
  auto kin = make_kinematics(c);
  const auto moves = circle(c, 10.0, -20.0, 30.0, 90.0, 90);
  for (double period : {0.001, 0.004}) {
    Segments s;
    JointEmitter em(*kin, period);
    for (const PlannedMove& m : moves) em.emit(m, s);
    double max_len = 0.0;
    const double dev = max_deviation(*kin, moves, s, &max_len);
    std::printf("delta Hermite, period %.0f ms: %zu pieces per joint, max deviation from exact IK %.3g um\n",
                period * 1e3, s.seg[0].size(), dev * 1e3);
    EXPECT_LE(max_len, period + 1e-12);
    EXPECT_LT(dev, period <= 0.001 ? 1e-5 : 1e-3);  // mm
    EXPECT_GT(s.seg[0].size(), moves.back().end_time_s() / period * 0.99);
  }
}

TEST(Sampler, TimelineFindsMovesAndEIsSynchronised) {
  PlannerConfig c = test::cartesian_config();
  const auto moves = circle(c, 110.0, 110.0, 1.0, 30.0, 24);
  MoveTimeline tl(8);
  for (const PlannedMove& m : moves) tl.push(m);
  EXPECT_EQ(tl.size(), 8u);
  CartesianSample out;
  EXPECT_FALSE(tl.sample(moves.front().start_time_s + 1e-6, out));  // dropped from the ring
  const PlannedMove& m = moves[20];
  for (double f : {0.1, 0.5, 0.9}) {
    const double t = m.start_time_s + f * m.duration_s;
    ASSERT_TRUE(tl.sample(t, out));
    const double s = std::hypot(out.pos_mm[0] - m.start_mm[0], out.pos_mm[1] - m.start_mm[1], out.pos_mm[2] - m.start_mm[2]);
    // E per mm of path is the same at every instant of the move
    EXPECT_NEAR((out.pos_mm[kE] - m.start_mm[kE]) / s, (m.end_mm[kE] - m.start_mm[kE]) / m.length_mm, 1e-9);
    EXPECT_NEAR(out.vel_mm_s[kE] / std::hypot(out.vel_mm_s[0], out.vel_mm_s[1], out.vel_mm_s[2]), m.unit[kE], 1e-9);
  }
  ASSERT_TRUE(tl.sample(moves.back().end_time_s(), out));
  EXPECT_NEAR(out.pos_mm[0], moves.back().end_mm[0], 1e-9);
}

}  // namespace
}  // namespace feedloop::planner
