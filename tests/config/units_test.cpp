// Unit expressions, key-suffix units and typo suggestions of the config library.
#include <gtest/gtest.h>

#include <cmath>

#include "config/diagnostics.hpp"
#include "config/map_reader.hpp"
#include "config/units.hpp"

namespace feedloop::config {
namespace {

TEST(ConfigUnits, ParsesCompoundUnitsToSi) {
  const auto accel = units::parse_unit("mm/s^2");
  ASSERT_TRUE(accel);
  EXPECT_DOUBLE_EQ(accel->to_si, 1e-3);
  EXPECT_EQ(units::dimension_name(accel->dim), "acceleration");

  const auto inertia = units::parse_unit("g*cm^2");  // thesis Table 2: 38 g cm^2
  ASSERT_TRUE(inertia);
  EXPECT_NEAR(38.0 * inertia->to_si, 3.8e-6, 1e-18);
  EXPECT_EQ(units::dimension_name(inertia->dim), "moment of inertia");

  const auto damping = units::parse_unit("N-s/m");  // delta paper Table I spelling
  ASSERT_TRUE(damping);
  EXPECT_EQ(units::dimension_name(damping->dim), "damping");
  EXPECT_EQ(damping->dim, units::parse_unit("Ns/m")->dim);

  const auto stiff = units::parse_unit("kN/m");
  ASSERT_TRUE(stiff);
  EXPECT_DOUBLE_EQ(stiff->to_si, 1e3);

  const auto per_s = units::parse_unit("s^-1");
  ASSERT_TRUE(per_s);
  EXPECT_EQ(per_s->dim, units::parse_unit("1/s")->dim);

  EXPECT_DOUBLE_EQ(units::parse_unit("mm/min")->to_si, 1e-3 / 60.0);
  EXPECT_DOUBLE_EQ(units::parse_unit("mm/s2")->to_si, 1e-3);
  EXPECT_DOUBLE_EQ(units::parse_unit("µm")->to_si, 1e-6);
}

TEST(ConfigUnits, HertzAndRadiansPerSecondShareADimensionButNotWithBareRate) {
  const auto hz = units::parse_unit("Hz");
  const auto rad_s = units::parse_unit("rad/s");
  ASSERT_TRUE(hz && rad_s);
  EXPECT_EQ(hz->dim, rad_s->dim);
  // 730 rad/s (delta paper Table I) is 116.18 Hz.
  EXPECT_NEAR(730.0 * rad_s->to_si / hz->to_si, 116.183, 1e-3);
  EXPECT_FALSE(hz->dim == units::parse_unit("1/s")->dim);
}

TEST(ConfigUnits, RejectsUnknownOrMalformedUnits) {
  EXPECT_FALSE(units::parse_unit("furlongs"));
  EXPECT_FALSE(units::parse_unit("mm/"));
  EXPECT_FALSE(units::parse_unit("m/s/s"));
  EXPECT_FALSE(units::parse_unit("mm^x"));
  EXPECT_FALSE(units::parse_unit(""));
}

TEST(ConfigUnits, KeySuffixFixesTheUnitLongestSuffixFirst) {
  EXPECT_EQ(units::dimension_name(units::unit_for_key("max_accel_mm_s2")->dim), "acceleration");
  EXPECT_EQ(units::dimension_name(units::unit_for_key("max_velocity_mm_s")->dim), "velocity");
  EXPECT_EQ(units::dimension_name(units::unit_for_key("steps_per_mm")->dim), "inverse length");
  EXPECT_EQ(units::dimension_name(units::unit_for_key("c1_ns_per_m")->dim), "damping");
  EXPECT_EQ(units::dimension_name(units::unit_for_key("k2_n_per_m")->dim), "stiffness");
  EXPECT_EQ(units::dimension_name(units::unit_for_key("holding_torque_nm")->dim), "torque");
  EXPECT_DOUBLE_EQ(units::unit_for_key("width_um")->to_si, 1e-6);
  EXPECT_FALSE(units::unit_for_key("kp"));
  EXPECT_FALSE(units::unit_for_key("damping"));
}

TEST(ConfigNumbers, SplitsValueAndUnitAndRoundTripsText) {
  double v = 0;
  std::string unit;
  ASSERT_TRUE(split_number("3000 mm/s^2", v, unit));
  EXPECT_DOUBLE_EQ(v, 3000.0);
  EXPECT_EQ(unit, "mm/s^2");
  ASSERT_TRUE(split_number("-212.1", v, unit));
  EXPECT_DOUBLE_EQ(v, -212.1);
  EXPECT_EQ(unit, "");
  ASSERT_TRUE(split_number("5um", v, unit));
  EXPECT_EQ(unit, "um");
  EXPECT_FALSE(split_number("fast", v, unit));
  EXPECT_FALSE(split_number(".inf", v, unit));
  for (double x : {0.013, 94.314, 1.21e5, -16.52, 3.8e-6, 0.1 + 0.2}) {
    double back = 0;
    ASSERT_TRUE(split_number(format_number(x), back, unit));
    EXPECT_EQ(back, x);
  }
}

TEST(ConfigSuggestions, EditDistanceAndClosestMatch) {
  EXPECT_EQ(edit_distance("steps_per_mn", "steps_per_mm"), 1u);
  EXPECT_EQ(edit_distance("kitten", "sitting"), 3u);
  EXPECT_EQ(closest_match("max_accel_mm_s", {"max_accel_mm_s2", "max_velocity_mm_s"}),
            "max_accel_mm_s2");
  EXPECT_EQ(closest_match("cartesain", {"cartesian", "corexy", "delta"}), "cartesian");
  EXPECT_EQ(closest_match("banana", {"cartesian", "corexy", "delta"}), "");
}

}  // namespace
}  // namespace feedloop::config
