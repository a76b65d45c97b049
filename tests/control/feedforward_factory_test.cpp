// engine::make_model_feedforward (engine/control_config.hpp): from a printer config to
// the gantry or delta feedforward, with clear errors for configs that lack the model it needs.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <string>
#include <cstdio>

#include "config/config.hpp"
#include "engine/control_config.hpp"

namespace feedloop::control {
namespace {

config::MachineConfig cartesian() {
  config::MachineConfig c;
  c.kinematics = config::Kinematics::cartesian;
  for (const char* n : {"x", "y", "z", "e"}) {
    config::AxisConfig a;
    a.name = n;
    a.min_mm = 0.0;
    a.max_mm = 200.0;
    c.axes.push_back(a);
  }
  config::GantryModelConfig gx, gy;
  gx.axis = "x";
  gy.axis = "y";
  gy.m2_kg = 1.07;
  gy.k1_n_per_m = 392e3;
  gy.k2_n_per_m = 19.7e3;
  gy.c1_ns_per_m = 411;
  gy.c2_ns_per_m = 71.5;
  gy.stepper.belt_unit_stiffness_n = 5910;
  c.model.gantry = {gx, gy};
  c.feedforward.type = config::FeedforwardType::lpv;
  return c;
}

config::MachineConfig delta() {
  config::MachineConfig c;
  c.kinematics = config::Kinematics::delta;
  config::DeltaGeometryConfig g;
  g.z_min_mm = 20.0;  // a thin slab keeps the test fast (the grid is 9 x 9 x 2 here)
  g.z_max_mm = 40.0;
  c.delta = g;
  c.model.delta_lpv = config::DeltaLpvConfig{};
  return c;
}

TEST(MakeModelFeedforward, GantryPreviewFromConfig) {
  config::MachineConfig c = cartesian();
  auto ff = engine::make_model_feedforward(c, 1e-3);
  ASSERT_TRUE(ff.ok()) << ff.error().message;
  // 20 ms at 1 kHz, and the velocity-jump window in front of it: 31 ms, 2 h + 1 = 31 periods.
  EXPECT_EQ((*ff)->preview_samples(), 20 + 31);
  EXPECT_STREQ((*ff)->name(), "lpv");
  c.feedforward.lpv.preview_ms = 10.0;
  auto ff2 = engine::make_model_feedforward(c, 0.25e-3);  // 4 kHz: 40 + (2 * 61 + 1)
  ASSERT_TRUE(ff2.ok()) << ff2.error().message;
  EXPECT_EQ((*ff2)->preview_samples(), 40 + 123);
  c.feedforward.lpv.jump_accel_mm_s2 = 0.0;  // no smoothing: the inverse's preview alone
  auto ff3 = engine::make_model_feedforward(c, 0.25e-3);
  ASSERT_TRUE(ff3.ok()) << ff3.error().message;
  EXPECT_EQ((*ff3)->preview_samples(), 40);
  // At rest it commands the reference.
  FeedforwardInput at;
  at.r_mm = {50.0, 120.0, 3.0, 1.0};
  (*ff)->reset(at);
  JointArray u{};
  for (int k = 0; k < 5; ++k) (*ff)->step(at, u);
  for (int j = 0; j < 4; ++j) EXPECT_NEAR(u[static_cast<size_t>(j)], at.r_mm[static_cast<size_t>(j)], 1e-8);
}

TEST(MakeModelFeedforward, ClearErrors) {
  config::MachineConfig c = cartesian();
  c.model.gantry.pop_back();
  auto e1 = engine::make_model_feedforward(c, 1e-3);
  ASSERT_FALSE(e1.ok());
  EXPECT_NE(e1.error().message.find("model.gantry.y"), std::string::npos) << e1.error().message;

  c = cartesian();
  c.feedforward.lpv.preview_ms = 1.0;
  auto e2 = engine::make_model_feedforward(c, 1e-3);
  ASSERT_FALSE(e2.ok());
  EXPECT_NE(e2.error().message.find("preview_ms"), std::string::npos) << e2.error().message;

  c = cartesian();
  c.model.gantry[0].m2_kg = -1.0;
  auto e3 = engine::make_model_feedforward(c, 1e-3);
  ASSERT_FALSE(e3.ok());
  EXPECT_NE(e3.error().message.find("joint 0"), std::string::npos) << e3.error().message;

  config::MachineConfig d = delta();
  d.model.delta_lpv.reset();
  auto e4 = engine::make_model_feedforward(d, 1e-3);
  ASSERT_FALSE(e4.ok());
  EXPECT_NE(e4.error().message.find("model.delta_lpv"), std::string::npos) << e4.error().message;

  d = delta();
  d.delta.reset();
  auto e5 = engine::make_model_feedforward(d, 1e-3);
  ASSERT_FALSE(e5.ok());
  EXPECT_NE(e5.error().message.find("delta"), std::string::npos) << e5.error().message;

  auto e6 = engine::make_model_feedforward(cartesian(), 0.0);
  EXPECT_FALSE(e6.ok());
}

TEST(MakeModelFeedforward, DeltaLpvAndFrozenCentre) {
  const auto t0 = std::chrono::steady_clock::now();
  auto lpv = engine::make_model_feedforward(delta(), 1e-3);
  const auto t1 = std::chrono::steady_clock::now();
  auto centre = engine::make_model_feedforward(delta(), 1e-3, /*freeze_at_centre=*/true);
  ASSERT_TRUE(lpv.ok()) << lpv.error().message;
  ASSERT_TRUE(centre.ok()) << centre.error().message;
  const double ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
  std::printf("delta feedforward design: 162 grid points in %.0f ms (%.2f ms per point)\n", ms, ms / 162.0);
  EXPECT_STREQ((*lpv)->name(), "lpv");
  EXPECT_STREQ((*centre)->name(), "lpv-centre");
  EXPECT_EQ((*lpv)->preview_samples(), 20 + 31);
  // Off centre the two differ during a move (the models differ), at rest both command r.
  FeedforwardInput at;
  at.nozzle_mm = {-80.0, 0.0, 30.0};
  at.r_mm = {290.0, 330.0, 330.0, 0.0};  // need not be consistent: linear model about r
  (*lpv)->reset(at);
  (*centre)->reset(at);
  JointArray ul{}, uc{};
  double max_diff = 0;
  for (int k = 0; k < 100; ++k) {
    FeedforwardInput in = at;
    in.r_mm[0] += 0.001 * k * k;  // accelerating carriage A
    (*lpv)->step(in, ul);
    (*centre)->step(in, uc);
    max_diff = std::max(max_diff, std::abs(ul[0] - uc[0]));
  }
  std::printf("delta at (-80,0,30), accelerating carriage: |u_lpv - u_centre| up to %.4f mm\n", max_diff);
  EXPECT_GT(max_diff, 1e-4);
}

TEST(MakeModelFeedforward, ExampleConfigs) {
  // The shipped examples, with their full grids (delta: 9 x 9 x 6 points over z 0..250 mm).
  for (const char* name : {"cartesian_sim.yaml", "delta_sim.yaml"}) {
    auto cfg = config::load_config_file(std::string(FEEDLOOP_SOURCE_DIR) + "/config/examples/" + name);
    ASSERT_TRUE(cfg.ok()) << cfg.error().to_string();
    const auto t0 = std::chrono::steady_clock::now();
    auto ff = engine::make_model_feedforward(cfg.value(), 1.0 / cfg->servo.rate_hz);
    const auto t1 = std::chrono::steady_clock::now();
    ASSERT_TRUE(ff.ok()) << name << ": " << ff.error().message;
    std::printf("%s: feedforward '%s' designed in %.0f ms, P = %d\n", name, (*ff)->name(),
                std::chrono::duration<double, std::milli>(t1 - t0).count(), (*ff)->preview_samples());
    const config::LpvFeedforwardConfig& lpv = cfg->feedforward.lpv;
    const int window = lpv.jump_accel_mm_s2 > 0.0
                           ? 2 * static_cast<int>(std::floor(0.5 * (lpv.jump_window_ms * 1e-3 * cfg->servo.rate_hz - 1.0))) + 1
                           : 0;
    EXPECT_EQ((*ff)->preview_samples(), static_cast<int>(std::lround(lpv.preview_ms * 1e-3 * cfg->servo.rate_hz)) + window);
  }
}

}  // namespace
}  // namespace feedloop::control
