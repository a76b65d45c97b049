// The delta plant in the time domain: driven through its three carriage ports it follows the
// commanded joint positions, puts the nozzle where the kinematics say, and is deterministic.
#include <cmath>
#include <cstdio>
#include <vector>

#include <gtest/gtest.h>

#include "model/delta_kinematics.hpp"
#include "sim/delta_plant.hpp"
#include "sim/step_driver.hpp"

namespace feedloop::sim {
namespace {

// Moves the nozzle from `from` to `to` on a straight line in duration_s (smoothstep in time),
// step updates every 20 us, encoder reads every 1 ms; returns the encoder trace.
std::vector<int64_t> drive_line(DeltaPlant& plant, const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                                double duration_s, double hold_s) {
  const model::DeltaGeometry& geo = plant.params().model.geometry;
  const Eigen::Vector3d q0 = model::inverse_kinematics(geo, from).value();
  std::array<StepDriver, 3> drivers{StepDriver(plant.carriage_port(0), plant.params().mm_per_step),
                                    StepDriver(plant.carriage_port(1), plant.params().mm_per_step),
                                    StepDriver(plant.carriage_port(2), plant.params().mm_per_step)};
  std::vector<int64_t> trace;
  const double dt = 2e-5;
  for (int k = 1; k * dt <= duration_s + hold_s; ++k) {
    const double t = k * dt;
    const double s = std::min(t / duration_s, 1.0);
    const Eigen::Vector3d pos = from + (to - from) * (s * s * (3.0 - 2.0 * s));
    const Eigen::Vector3d q = model::inverse_kinematics(geo, pos).value();
    for (int i = 0; i < 3; ++i) drivers[static_cast<size_t>(i)].update(t, q[i] - q0[i]);
    if (k % 50 == 0)
      for (int i = 0; i < 3; ++i) trace.push_back(plant.carriage_port(i).read_encoder_counts(t));
  }
  return trace;
}

// 20 kHz substeps keep the sanitizer build quick (the arm modes, <= 3 kHz, stay well inside RK4's range).
DeltaPlantParams fast_params() {
  DeltaPlantParams p;
  p.substep_hz = 20000.0;
  return p;
}

TEST(DeltaMotion, FollowsTheCommandAndPlacesTheNozzle) {
  auto plant = std::move(DeltaPlant::create(fast_params()).value());
  const Eigen::Vector3d start(0, 0, 30), target(40, 20, 40);
  drive_line(*plant, start, target, 0.2, 0.3);
  // Reference: a plant powered on at the target sits in the static equilibrium the moved plant
  // must reach (gravity sag and its change of distribution with position included), up to the
  // commanded positions' step rounding.
  DeltaPlantParams at_target = fast_params();
  at_target.initial_nozzle_mm = target;
  auto ref = std::move(DeltaPlant::create(at_target).value());
  const model::DeltaGeometry& geo = plant->params().model.geometry;
  const Eigen::Vector3d dq = model::inverse_kinematics(geo, target).value() - model::inverse_kinematics(geo, start).value();
  double worst_joint_um = 0.0, sag_change_um = 0.0;
  for (int i = 0; i < 3; ++i) {
    const double rounding_mm = plant->commanded_rel_mm(i) - dq[i];
    worst_joint_um = std::max(worst_joint_um, std::abs(plant->carriage_mm(i) - ref->carriage_mm(i) - rounding_mm) * 1e3);
    sag_change_um = std::max(sag_change_um, std::abs(plant->carriage_rel_mm(i) - plant->commanded_rel_mm(i)) * 1e3);
  }
  const double nozzle_um = (plant->nozzle_mm() - ref->nozzle_mm()).norm() * 1e3;
  std::printf("joint vs static equilibrium %.3f um (load redistribution shifts joints by up to %.2f um); nozzle %.2f um\n",
              worst_joint_um, sag_change_um, nozzle_um);
  EXPECT_LT(worst_joint_um, 0.5);
  EXPECT_LT(nozzle_um, 12.5);  // step rounding (<= 6.25 um per joint) mapped through J
  EXPECT_GT(sag_change_um, 1.0);  // gravity load moves between carriages with the position
  EXPECT_EQ(plant->late_events(), 0);
}

TEST(DeltaMotion, DeterministicForASeedAndNoisyAcrossSeeds) {
  auto run = [](uint64_t seed) {
    DeltaPlantParams p = fast_params();
    p.seed = seed;
    auto plant = std::move(DeltaPlant::create(p).value());
    return drive_line(*plant, {0, 0, 30}, {-30, 10, 30}, 0.05, 0.01);
  };
  const auto a = run(3), b = run(3), c = run(4);
  EXPECT_EQ(a, b);
  EXPECT_NE(a, c);
}

TEST(DeltaMotion, RejectsAnUnreachableStart) {
  DeltaPlantParams p;
  p.initial_nozzle_mm = {400.0, 0.0, 30.0};
  auto r = DeltaPlant::create(p);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("initial position"), std::string::npos);
}

}  // namespace
}  // namespace feedloop::sim
