// Ranking of the speed assignments on a small path (one layer of the fin test part): Table III's
// order (sharp-corner: error well below constant at a time close to it; every-transition: lowest
// error, longest time) and the arc-length variant no worse than the sharp-corner one.
#include <gtest/gtest.h>

#include <filesystem>

#include "maneuver/controller.hpp"
#include "maneuver/gcode_path.hpp"
#include "maneuver/simulation.hpp"
#include "maneuver/test_part.hpp"

namespace feedloop::maneuver {
namespace {

struct Figures {
  double max_m, iae, time_s;
};

Figures run(const std::vector<Vec3>& wp_m, SpeedProfile prof, Parameterization param) {
  auto path = PiecewiseLinearPath::create(wp_m, param);
  auto speed = SpeedAssignment::create(*path, prof, SpeedParams{});
  const CartesianDcPlant plant;
  ManeuverGains g;
  const double mean_seg = path->length_m() / static_cast<double>(path->segments());
  if (param == Parameterization::arc_length) g.mu *= mean_seg * mean_seg;
  const ManeuverController ctl(plant, g);
  SimOptions so;
  so.record_every = 0;
  so.split_at_waypoints = param == Parameterization::arc_length;
  auto r = simulate(*path, *speed, ctl, plant, so);
  EXPECT_TRUE(r->finished);
  return {r->max_cross_m, r->iae_cross_m_s, r->total_time_s};
}

TEST(ManeuverRanking, TableIIIOrderOnOneLayer) {
  TestPartOptions tp;
  tp.layers = 1;
  GcodePathOptions gp;
  gp.layers = 1;
  gp.feature = "External perimeter";
  auto wp = extrusion_path_from_gcode(test_part_gcode(tp), "fin", gp);
  ASSERT_TRUE(wp.ok()) << wp.error().to_string();
  std::vector<Vec3> wp_m;
  for (const Vec3& p : *wp) wp_m.push_back(p * 1e-3);

  const Figures cs = run(wp_m, SpeedProfile::constant, Parameterization::unit);
  const Figures et = run(wp_m, SpeedProfile::every_transition, Parameterization::unit);
  const Figures sc = run(wp_m, SpeedProfile::sharp_corner, Parameterization::unit);
  const Figures arc = run(wp_m, SpeedProfile::sharp_corner_arc, Parameterization::arc_length);
  // Constant speed: about the path length over m_s (1.80 s for 180 mm).
  EXPECT_NEAR(cs.time_s, 0.1799 / 0.1, 0.02);
  // Sharp-corner: max error well below constant speed (paper: 2x; here more), time close to it.
  EXPECT_LT(sc.max_m, 0.5 * cs.max_m);
  EXPECT_LT(sc.iae, cs.iae);
  EXPECT_LT(sc.time_s, 1.2 * cs.time_s);
  // Every transition: lowest error, longest time.
  EXPECT_LT(et.max_m, sc.max_m);
  EXPECT_LT(et.iae, sc.iae);
  EXPECT_GT(et.time_s, 1.5 * sc.time_s);
  // Arc-length variant: faster than sharp-corner without more error.
  EXPECT_LT(arc.time_s, sc.time_s);
  EXPECT_LE(arc.max_m, sc.max_m);
  EXPECT_LT(arc.max_m, 0.5 * cs.max_m);
}

// Real slicer output: the corpus star prism's external perimeter has 0.11 mm segments at the tips
// beside 28.5 mm edges, where Eq. 67 both crawls (slow-down proportional to the long edges) and
// jolts (a transition micrometres long on the short ones); the arc variant does neither.
TEST(ManeuverRanking, CorpusStarPrismArcVariantBeatsEq67) {
  const std::string file = std::string(FEEDLOOP_SHARED_DIR) + "/gcode/star_prism_cartesian.gcode";
  if (!std::filesystem::exists(file)) GTEST_SKIP() << "corpus not found: " << file;
  GcodePathOptions gp;
  gp.layers = 2;
  gp.layer_stride = 2;
  gp.feature = "External perimeter";
  auto wp = extrusion_path_from_gcode_file(file, gp);
  ASSERT_TRUE(wp.ok()) << wp.error().to_string();
  std::vector<Vec3> wp_m;
  for (const Vec3& p : *wp) wp_m.push_back(p * 1e-3);
  const Figures cs = run(wp_m, SpeedProfile::constant, Parameterization::unit);
  const Figures sc = run(wp_m, SpeedProfile::sharp_corner, Parameterization::unit);
  const Figures arc = run(wp_m, SpeedProfile::sharp_corner_arc, Parameterization::arc_length);
  EXPECT_GT(sc.time_s, 1.8 * cs.time_s);   // 10 layers: 2.25x
  EXPECT_LT(arc.time_s, 0.6 * sc.time_s);  // 10 layers: 0.50x
  EXPECT_LT(arc.max_m, 0.4 * sc.max_m);    // 10 layers: 0.19x
  EXPECT_LT(arc.iae, 0.5 * sc.iae);        // 10 layers: 0.31x
}

}  // namespace
}  // namespace feedloop::maneuver
