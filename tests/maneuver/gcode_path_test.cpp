// Waypoints from G-code: the generated test part, relative/absolute modes, errors, and the corpus
// star prism (skipped when the corpus is absent).
#include <gtest/gtest.h>

#include <filesystem>

#include "maneuver/gcode_path.hpp"
#include "maneuver/test_part.hpp"

namespace feedloop::maneuver {
namespace {

TEST(ManeuverGcodePath, TestPartLayersAndJoins) {
  GcodePathOptions gp;
  gp.layers = 3;
  gp.feature = "External perimeter";
  auto wp = extrusion_path_from_gcode(test_part_gcode(), "fin", gp);
  ASSERT_TRUE(wp.ok()) << wp.error().to_string();
  // fin: (0,0), 25 bottom points, 24 top points, back to (0,0): 51 waypoints per layer.
  ASSERT_EQ(wp->size(), 3u * 51u);
  EXPECT_NEAR(((*wp)[0] - Vec3(90, 90, 0.4)).norm(), 0.0, 1e-9);
  EXPECT_NEAR(((*wp)[25] - Vec3(170, 90, 0.4)).norm(), 1e-3, 1e-3);  // the tip (4 decimals in G-code)
  EXPECT_NEAR(((*wp)[51] - Vec3(90, 90, 0.8)).norm(), 0.0, 1e-9);      // layer 2 starts 0.4 mm up
  auto too_many = extrusion_path_from_gcode(test_part_gcode(), "fin", GcodePathOptions{0, 11, 1, ""});
  ASSERT_FALSE(too_many.ok());
  EXPECT_NE(too_many.error().message.find("found 10 of the 11 layers"), std::string::npos);
}

TEST(ManeuverGcodePath, RelativeModesStrideAndBadLines) {
  const std::string g =
      "G90\nM83\nG1 Z0.2\nG1 X0 Y0\nG1 X10 E1\nG1 Y10 E1\nG1 X20 Y20\n"   // layer 0 (then travel)
      "G1 Z0.4\nG91\nG1 X-20 Y-20\nG1 X5 E1\n"                          // layer 1 (relative)
      "G90\nG1 Z0.6\nG92 X100 Y100 E0\nG1 X101 E1\n";  // layer 2: G90 makes E absolute too (Marlin)
  auto all = extrusion_path_from_gcode(g, "g", GcodePathOptions{0, 3, 1, ""});
  ASSERT_TRUE(all.ok()) << all.error().to_string();
  ASSERT_EQ(all->size(), 7u);
  EXPECT_NEAR(((*all)[2] - Vec3(10, 10, 0.2)).norm(), 0.0, 1e-12);
  EXPECT_NEAR(((*all)[4] - Vec3(5, 0, 0.4)).norm(), 0.0, 1e-12);
  EXPECT_NEAR(((*all)[6] - Vec3(101, 100, 0.6)).norm(), 0.0, 1e-12);
  auto stride = extrusion_path_from_gcode(g, "g", GcodePathOptions{0, 2, 2, ""});
  ASSERT_TRUE(stride.ok());
  ASSERT_EQ(stride->size(), 5u);  // layers 0 and 2
  EXPECT_NEAR((*stride)[4].z(), 0.6, 1e-12);
  auto bad = extrusion_path_from_gcode("G1 X0\nG1 X1 Q\n", "bad.gcode", GcodePathOptions{});
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.error().where.line, 2);
}

TEST(ManeuverGcodePath, CorpusStarPrismTenLayers) {
  const std::string file = std::string(FEEDLOOP_SHARED_DIR) + "/gcode/star_prism_cartesian.gcode";
  if (!std::filesystem::exists(file)) GTEST_SKIP() << "corpus not found: " << file;
  GcodePathOptions gp;
  gp.first_layer = 1;  // above the first layer (which has the skirt)
  gp.layers = 10;
  gp.layer_stride = 2;  // 0.2 mm layers: every other one is 0.4 mm apart
  gp.feature = "External perimeter";
  auto wp = extrusion_path_from_gcode_file(file, gp);
  ASSERT_TRUE(wp.ok()) << wp.error().to_string();
  EXPECT_GT(wp->size(), 10u * 10u);  // a 5-point star has at least 10 corners per loop
  double z_min = 1e9, z_max = -1e9;
  for (const Vec3& p : *wp) {
    z_min = std::min(z_min, p.z());
    z_max = std::max(z_max, p.z());
  }
  EXPECT_NEAR(z_max - z_min, 9 * 0.4, 1e-6);
}

}  // namespace
}  // namespace feedloop::maneuver
