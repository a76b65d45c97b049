// Segment skipping (output-maneuvering-cartesian Sect. V-A): with theta_n - theta_{n-1} = 1 a fixed
// step advances theta by m_s dt / ||Delta_n|| and jumps over short segments; arc-length theta
// with steps split at waypoints enters every segment in order.
#include <gtest/gtest.h>

#include <cmath>

#include "maneuver/controller.hpp"
#include "maneuver/simulation.hpp"

namespace feedloop::maneuver {
namespace {

// 10 mm straight, a 0.02 mm jog up, 0.03 mm on, 0.02 mm back down (a slicer's tiny notch),
// 10 mm straight, a 90-degree turn, 10 mm.
std::vector<Vec3> notch_path() {
  return {{0, 0, 0},          {0.01, 0, 0},       {0.01, 0.02e-3, 0},  {0.01003, 0.02e-3, 0},
          {0.01003, 0, 0},    {0.02003, 0, 0},    {0.02003, 0.01, 0}};
}

struct SkipRun {
  SimResult r;
  std::vector<size_t> visited;  // number of recorded steps on each segment
};

SkipRun run(Parameterization param, SpeedProfile prof, bool split, double dt_s) {
  auto path = PiecewiseLinearPath::create(notch_path(), param);
  auto speed = SpeedAssignment::create(*path, prof, SpeedParams{});
  const CartesianDcPlant plant;
  ManeuverGains g;
  if (param == Parameterization::arc_length) g.mu = 1000.0 * 0.005 * 0.005;
  const ManeuverController ctl(plant, g);
  SimOptions so;
  so.dt_s = dt_s;
  so.split_at_waypoints = split;
  so.record_every = 1;
  SkipRun out{*simulate(*path, *speed, ctl, plant, so), std::vector<size_t>(path->segments() + 1, 0)};
  for (const SimSample& s : out.r.samples) ++out.visited[s.segment];
  return out;
}

TEST(ManeuverSkip, UnitParameterisationJumpsOverTheNotch) {
  // At m_s = 0.1 m/s on a 0.02 mm segment theta' = 5000 /s: a 1 ms step moves theta by 5.
  const SkipRun unit = run(Parameterization::unit, SpeedProfile::constant, false, 1e-3);
  ASSERT_TRUE(unit.r.finished);
  EXPECT_GE(unit.r.skipped_segments, 2u);
  size_t never = 0;
  for (size_t n = 1; n < unit.r.segment_entry_s.size(); ++n) never += unit.r.segment_entry_s[n] < 0.0;
  EXPECT_GE(never, 2u) << "notch segments the controller never followed";
  EXPECT_EQ(never, unit.r.skipped_segments);
}

TEST(ManeuverSkip, ArcLengthWithSplitStepsVisitsEverySegmentInOrder) {
  for (auto prof : {SpeedProfile::constant, SpeedProfile::sharp_corner_arc}) {
    const SkipRun arc = run(Parameterization::arc_length, prof, true, 1e-3);
    ASSERT_TRUE(arc.r.finished) << to_string(prof);
    EXPECT_EQ(arc.r.skipped_segments, 0u);
    // Every segment was entered, in order.
    ASSERT_EQ(arc.r.segment_entry_s.size(), 7u);
    for (size_t n = 2; n <= 6; ++n) {
      EXPECT_GT(arc.r.segment_entry_s[n], arc.r.segment_entry_s[n - 1]) << to_string(prof) << " segment " << n;
    }
  }
}

}  // namespace
}  // namespace feedloop::maneuver
