// planner.cornering: speed_change and planner.max_speed_change_mm_s: parsed, range-checked with
// file:line:col, emitted and read back, and mapped onto the planner's policy.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include "config/config.hpp"
#include "engine/config_mapping.hpp"

namespace feedloop {
namespace {

// The default config with the planner's cornering line replaced and extra planner keys added.
std::string yaml_with(const std::string& cornering, const std::string& extra) {
  std::string y(config::default_config_yaml());
  const std::string jd = "cornering: junction_deviation";
  const size_t at = y.find(jd);
  if (at == std::string::npos) return "";
  y.replace(at, jd.size(), "cornering: " + cornering);
  y.insert(y.find("\nplanner:\n") + 10, extra);
  return y;
}

TEST(SpeedChangeConfig, ParsedEmittedAndMapped) {
  const std::string y = yaml_with("speed_change", "  max_speed_change_mm_s: 300\n");
  ASSERT_FALSE(y.empty()) << "default config has no 'cornering: junction_deviation' line";
  auto cfg = config::load_config_text(y, "sc.yaml");
  ASSERT_TRUE(cfg) << cfg.error().to_string();
  EXPECT_EQ(cfg.value().planner.cornering, config::Cornering::speed_change);
  EXPECT_DOUBLE_EQ(cfg.value().planner.max_speed_change_mm_s, 300.0);
  const std::string emitted = config::to_yaml(cfg.value());
  EXPECT_NE(emitted.find("cornering: speed_change"), std::string::npos);
  EXPECT_NE(emitted.find("max_speed_change_mm_s: 300"), std::string::npos);
  auto again = config::load_config_text(emitted, "emitted.yaml");
  ASSERT_TRUE(again) << again.error().to_string();
  EXPECT_TRUE(again.value() == cfg.value());
  const planner::PlannerConfig p = engine::planner_config(cfg.value());
  EXPECT_EQ(p.cornering, planner::CorneringPolicy::speed_change);
  EXPECT_DOUBLE_EQ(p.max_speed_change_mm_s, 300.0);
  // the default is the thesis's normal setting, 15 mm/s
  EXPECT_DOUBLE_EQ(config::default_config().planner.max_speed_change_mm_s, 15.0);
}

TEST(SpeedChangeConfig, NonPositiveLimitIsAnErrorWithItsLocation) {
  const std::string y = yaml_with("speed_change", "  max_speed_change_mm_s: 0\n");
  const std::vector<Error> errs = config::check_config_text(y, "sc.yaml");
  ASSERT_EQ(errs.size(), 1u);
  const std::string msg = errs[0].to_string();
  EXPECT_NE(msg.find("max_speed_change_mm_s must be > 0"), std::string::npos) << msg;
  // the key sits on the line after "planner:", its value at column 26
  std::string d(config::default_config_yaml());
  const int line = 1 + static_cast<int>(std::count(d.begin(), d.begin() + static_cast<long>(d.find("\nplanner:\n")) + 1, '\n')) + 1;
  EXPECT_NE(msg.find("sc.yaml:" + std::to_string(line) + ":26:"), std::string::npos) << msg;
}

}  // namespace
}  // namespace feedloop
