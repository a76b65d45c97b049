// External plant v1 (DESIGN.md) from feedloop's side, against tests/sim/plants/lag_plant.py, a
// plant the simulator did not write: lock-step exchange, the plant's answers through the encoder
// model, and a plant that exits early, answers garbage, stays silent or fails the handshake. The
// script checks the contract from its side (handshake, t_s = k * period_s, one number per axis)
// and exits with status 2 when it is broken, which the tests would see as a fault.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "sim/external_plant.hpp"

namespace feedloop::sim {
namespace {

const std::string kScript = std::string(FEEDLOOP_SOURCE_DIR) + "/tests/sim/plants/lag_plant.py";

ExternalPlantParams params(const std::string& options, int axes = 2) {
  ExternalPlantParams p;
  p.command = "python3 " + kScript + " " + options;
  p.period_s = 0.001;
  for (int i = 0; i < axes; ++i) {
    ExternalAxisParams a;
    a.name = i == 0 ? "x" : "y";
    a.mm_per_step = 0.01;
    a.start_mm = i == 0 ? 0.0 : 5.0;
    a.encoder.resolution_um = 1.0;
    a.encoder.noise_um = 0.0;
    p.axes.push_back(a);
  }
  return p;
}

TEST(ExternalPlant, LockStepCarriagesFollowTheStaircaseThroughThePlantsDynamics) {
  auto plant = ExternalPlant::start(params("--freq-hz 50 --zeta 0.5"));
  ASSERT_TRUE(plant.ok()) << plant.error().message;
  ExternalPlant& p = *plant.value();
  ExternalAxisPort& x = p.port(0);
  ExternalAxisPort& y = p.port(1);
  // 1 mm on x (100 steps) over 10 ms from t = 2 ms (the first period is at rest, as the contract
  // says: the plant learns the start position from it); y stays.
  p.advance_to(0.002);
  for (int i = 0; i < 100; ++i) x.step(0.002 + 1e-4 * (i + 1), +1);
  EXPECT_EQ(x.read_encoder_counts(0.0125), std::llround(x.carriage_mm() * 1e3));
  EXPECT_LT(x.carriage_mm(), 0.9);  // 50 Hz, zeta 0.5: still on its way after 10 ms
  p.advance_to(0.2);
  EXPECT_FALSE(p.faulted()) << p.fault();
  EXPECT_EQ(p.periods(), 200u);
  EXPECT_NEAR(x.carriage_mm(), 1.0, 1e-3);   // settled
  EXPECT_NEAR(x.read_encoder_counts(0.2), 1000, 1);
  EXPECT_NEAR(y.carriage_mm(), 5.0, 1e-12);  // at rest where it started
  EXPECT_EQ(y.read_encoder_counts(0.2), 0);  // counts are zero at the start position
}

TEST(ExternalPlant, OvershootShowsThePlantIsNotAnIdealMotor) {
  auto plant = ExternalPlant::start(params("--freq-hz 50 --zeta 0.1", 1));
  ASSERT_TRUE(plant.ok()) << plant.error().message;
  ExternalPlant& p = *plant.value();
  p.advance_to(0.002);
  for (int i = 0; i < 100; ++i) p.port(0).step(0.002 + 1e-6 * (i + 1), +1);  // a 1 mm jump at t = 2 ms
  double peak_mm = 0.0;
  for (int k = 1; k <= 40; ++k) {
    p.advance_to(k * 1e-3);
    peak_mm = std::max(peak_mm, p.port(0).carriage_mm());
  }
  EXPECT_GT(peak_mm, 1.5);  // zeta 0.1: ~73 % overshoot
  EXPECT_FALSE(p.faulted()) << p.fault();
}

TEST(ExternalPlant, APlantThatExitsEarlyStopsWithItsStatus) {
  auto plant = ExternalPlant::start(params("--exit-after 5"));
  ASSERT_TRUE(plant.ok()) << plant.error().message;
  ExternalPlant& p = *plant.value();
  p.advance_to(0.1);
  ASSERT_TRUE(p.faulted());
  EXPECT_NE(p.fault().find("exited with status 3"), std::string::npos) << p.fault();
  EXPECT_NE(p.fault().find("t = 0.005000 s"), std::string::npos) << p.fault();
  EXPECT_EQ(p.periods(), 4u);
  p.advance_to(0.2);  // nothing more is exchanged and nothing blocks
  EXPECT_EQ(p.periods(), 4u);
}

TEST(ExternalPlant, GarbageIsAClearErrorThatQuotesTheLine) {
  auto plant = ExternalPlant::start(params("--garbage-after 3"));
  ASSERT_TRUE(plant.ok()) << plant.error().message;
  ExternalPlant& p = *plant.value();
  p.advance_to(0.05);
  ASSERT_TRUE(p.faulted());
  EXPECT_NE(p.fault().find("malformed line"), std::string::npos) << p.fault();
  EXPECT_NE(p.fault().find("expected 2 numbers, got '1.0 banana'"), std::string::npos) << p.fault();
  EXPECT_EQ(p.periods(), 2u);
}

TEST(ExternalPlant, SilenceStopsAfterTheTimeout) {
  ExternalPlantParams pp = params("--silent-after 2");
  pp.answer_timeout_s = 0.3;  // the contract's 5 s, shortened for the test (not the handshake's)
  auto plant = ExternalPlant::start(pp);
  ASSERT_TRUE(plant.ok()) << plant.error().message;
  ExternalPlant& p = *plant.value();
  p.advance_to(0.05);
  ASSERT_TRUE(p.faulted());
  EXPECT_NE(p.fault().find("did not answer within 0.3 s"), std::string::npos) << p.fault();
  EXPECT_EQ(p.periods(), 1u);
}  // the destructor kills the sleeping plant within 1 s

TEST(ExternalPlant, AWrongHandshakeOrAMissingCommandIsAnErrorAtStart) {
  auto greeting = ExternalPlant::start(params("--greeting hello"));
  ASSERT_FALSE(greeting.ok());
  EXPECT_NE(greeting.error().message.find("answered the handshake with 'hello' instead of 'ready'"),
            std::string::npos)
      << greeting.error().message;
  ExternalPlantParams missing = params("");
  missing.command = "no-such-plant-command-xyz";
  auto none = ExternalPlant::start(missing);
  ASSERT_FALSE(none.ok());
  // Seen at the handshake ("exited with status 127") or, on a loaded machine where the exit lands
  // after the first exchange began, as the plant's fault ("exited (status 127) at t = 0 ...").
  EXPECT_NE(none.error().message.find("status 127"), std::string::npos) << none.error().message;
  EXPECT_NE(none.error().message.find("no-such-plant-command-xyz"), std::string::npos)
      << none.error().message;
}

}  // namespace
}  // namespace feedloop::sim
