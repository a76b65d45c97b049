// Seeded random property test (Ruckig style): random move sequences with tiny, zero-length,
// E-only and reversing moves, random feeds, accelerations, windows, the three cornering policies
// and profiles. Every emitted move must be finite, continuous with its neighbours, within its
// limits, its pieces must cover exactly its length, and the queue must always suffice to stop.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "planner/profile.hpp"
#include "planner_test_util.hpp"

namespace feedloop::planner {
namespace {

TEST(PlannerProperties, RandomSequencesKeepTheInvariants) {
  std::mt19937_64 rng(20261122);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  long checked = 0;
  for (int trial = 0; trial < 60; ++trial) {
    PlannerConfig c = test::cartesian_config();
    c.lookahead_moves = 2 + static_cast<size_t>(u01(rng) * 40);
    c.cornering = trial % 3 == 2   ? CorneringPolicy::sharp_corner
                  : trial % 3 == 1 ? CorneringPolicy::speed_change
                                   : CorneringPolicy::junction_deviation;
    c.max_speed_change_mm_s = 1.0 + 60.0 * static_cast<double>((trial * 37) % 61) / 61.0;  // keeps rng's sequence
    c.profile = trial % 4 == 3 ? ProfileShape::scurve : ProfileShape::trapezoid;
    c.min_cruise_ratio = u01(rng) * 0.9;
    test::Recorder rec;
    Planner p(c, rec);
    rec.planner = &p;
    std::vector<double> dv2;
    Vec4 pos{110, 110, 10, 0};
    p.set_position(pos);
    const int n = 300;
    for (int i = 0; i < n; ++i) {
      const double r = u01(rng);
      Vec4 next = pos;
      if (r < 0.05) {
        // zero length: dropped
      } else if (r < 0.15) {
        next[kE] += (u01(rng) - 0.6) * 2.0;  // E-only
      } else if (r < 0.25) {
        next[kX] += (u01(rng) - 0.5) * 1e-4;  // tiny
      } else if (r < 0.35) {
        next[kX] = pos[kX] - 0.5 * (u01(rng) + 0.1);  // reversal along x
      } else {
        const double ang = u01(rng) * 2.0 * M_PI, len = std::pow(10.0, u01(rng) * 3.0 - 1.5);
        next[kX] = std::clamp(pos[kX] + len * std::cos(ang), 0.0, 220.0);
        next[kY] = std::clamp(pos[kY] + len * std::sin(ang), 0.0, 220.0);
        next[kZ] = std::clamp(pos[kZ] + (u01(rng) < 0.1 ? 0.2 : 0.0), 0.0, 250.0);
        next[kE] += u01(rng) < 0.7 ? 0.03 * len : 0.0;
      }
      const double v = 1.0 + u01(rng) * 400.0, a = 100.0 + u01(rng) * 4000.0;
      const uint64_t before = p.moves_added();
      p.add_move({next, v, a, i});
      if (p.moves_added() > before) dv2.push_back(0.0);  // filled from the emitted move below
      pos = next;
      ASSERT_LE(p.queued(), c.lookahead_moves);
    }
    p.flush();
    const auto& mv = rec.moves;
    ASSERT_EQ(mv.size(), dv2.size());
    for (size_t i = 0; i < mv.size(); ++i) dv2[i] = 2.0 * mv[i].accel_mm_s2 * mv[i].length_mm;
    for (size_t i = 0; i < mv.size(); ++i) {
      const PlannedMove& m = mv[i];
      ++checked;
      ASSERT_TRUE(std::isfinite(m.duration_s) && m.duration_s > 0.0) << trial << "/" << i;
      ASSERT_TRUE(std::isfinite(m.v_cruise_mm_s));
      EXPECT_LE(m.v_entry_mm_s, m.v_cruise_mm_s * (1 + 1e-9) + 1e-12);
      EXPECT_LE(m.v_exit_mm_s, m.v_cruise_mm_s * (1 + 1e-9) + 1e-12);
      for (int a = 0; a < kAxes; ++a) {
        EXPECT_LE(std::abs(m.unit[a]) * m.v_cruise_mm_s, c.max_axis_velocity_mm_s[a] * (1 + 1e-9));
      }
      const ProfilePiece& last = m.pieces[m.piece_count - 1];
      EXPECT_NEAR(last.distance_mm(last.duration_s), m.length_mm, 1e-9 + 1e-9 * m.length_mm) << trial << "/" << i;
      EXPECT_NEAR(last.velocity_mm_s(last.duration_s), m.v_exit_mm_s, 1e-6);
      if (i + 1 < mv.size()) {
        EXPECT_NEAR(m.v_exit_mm_s, mv[i + 1].v_entry_mm_s, 1e-6) << trial << "/" << i;
        EXPECT_NEAR(m.end_time_s(), mv[i + 1].start_time_s, 1e-9);
        if (!m.kinematic || !mv[i + 1].kinematic) {
          EXPECT_EQ(m.v_exit_mm_s, 0.0);
        }
      }
      double room = 0.0;
      for (uint64_t k = i + 1; k < rec.added_at_emit[i] && k < mv.size(); ++k) room += dv2[k];
      EXPECT_LE(m.v_exit_mm_s * m.v_exit_mm_s, room * (1 + 1e-9) + 1e-9) << trial << "/" << i;
      if (c.profile == ProfileShape::scurve) {
        EXPECT_TRUE(m.jerk_bounded) << trial << "/" << i;
        for (int k = 0; k < m.piece_count; ++k) {
          const ProfilePiece& pc = m.pieces[k];
          EXPECT_LE(std::abs(pc.jerk_mm_s3), c.max_jerk_mm_s3 * (1 + 1e-9));
          EXPECT_LE(std::abs(pc.accel_mm_s2(pc.duration_s)), m.accel_mm_s2 * (1 + 1e-9));
        }
      }
      // the sampled path ends exactly at the end point
      const PathState st = path_state(m, m.duration_s);
      EXPECT_NEAR(st.s_mm, m.length_mm, 1e-9 + 1e-9 * m.length_mm);
    }
    EXPECT_EQ(mv.back().v_exit_mm_s, 0.0);
  }
  EXPECT_GT(checked, 10000);
}

}  // namespace
}  // namespace feedloop::planner
