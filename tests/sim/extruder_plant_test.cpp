// The compliant extruder (sim/extruder_plant.hpp) and the pressure advance measured on it
// (sim/experiments/extrusion_error.hpp, docs/pressure_advance.md).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>

#include "sim/experiments/extrusion_error.hpp"
#include "sim/extruder_plant.hpp"

namespace feedloop::sim {
namespace {

TEST(ExtruderPlant, SteadyFlowEqualsTheMotorsAfterALagThatGrowsAsTheFlowFalls) {
  ExtruderPlant plant;
  const double area = plant.filament_area_mm2();
  for (double q : {2.0, 10.0}) {
    plant.reset(0.0);
    const double v = q / area;  // filament mm/s
    const double dt = 1e-4;
    double t = 0.0, t63 = -1.0;
    while (t < 5.0) {
      t += dt;
      plant.step(v * t, dt);
      if (t63 < 0.0 && plant.nozzle_flow_mm3_s() >= 0.632 * q) t63 = t;
    }
    EXPECT_NEAR(plant.nozzle_flow_mm3_s(), q, 1e-3 * q);
    // The spring holds the force the flow law needs: F = A (q / c)^(1/n).
    const ExtruderPlantParams& p = plant.params();
    EXPECT_NEAR(plant.filament_force_n(),
                p.force_ref_n * std::pow(q / p.flow_ref_mm3_s, 1.0 / p.flow_exponent),
                1e-3 * p.force_ref_n);
    // The rise is slower than the linearised tau at the final flow (the force starts at 0, where
    // the power law's slope is 0) and of its order.
    const double tau = plant.time_constant_s(q);
    EXPECT_GT(t63, tau) << q;
    EXPECT_LT(t63, 4.0 * tau) << q;
  }
  EXPECT_NEAR(plant.time_constant_s(2.0) / plant.time_constant_s(10.0),
              std::pow(5.0, 1.0 - 1.0 / 1.4), 1e-9);  // q^(1/n - 1)
}

TEST(ExtruderPlant, ThePlayDelaysTheFlowAfterAReversal) {
  ExtruderPlantParams p;
  p.play_mm = 0.2;
  ExtruderPlant plant(p);
  plant.reset(0.0);
  const double dt = 1e-4;
  for (int i = 0; i < 100; ++i) plant.step(-0.2 * (i + 1) / 100.0, dt);  // pull back 0.2 mm
  const double v0 = plant.extruded_mm3();
  // Pushing forward again: the first 0.2 mm only take up the play (no force, no flow).
  for (int i = 0; i < 100; ++i) plant.step(-0.2 + 0.19 * (i + 1) / 100.0, dt);
  EXPECT_EQ(plant.filament_force_n(), 0.0);
  EXPECT_NEAR(plant.extruded_mm3(), v0, 1e-12);
  for (int i = 0; i < 100; ++i) plant.step(-0.01 + 0.3 * (i + 1) / 100.0, dt);
  EXPECT_GT(plant.filament_force_n(), 1.0);
}

// The acceptance: pressure advance with the tuned K at least halves the extruded-volume
// error of the sample print on the compliant (Bowden) extruder; K = 0 leaves the motor on e(t).
TEST(ExtruderPressureAdvance, TunedAdvanceHalvesTheExtrudedVolumeErrorOfTheCube) {
  std::ifstream in(std::string(FEEDLOOP_SOURCE_DIR) + "/examples/gcode/cube20_3layers.gcode");
  ASSERT_TRUE(in.good());
  std::stringstream ss;
  ss << in.rdbuf();
  auto planned = plan_gcode(ss.str(), "cube20_3layers.gcode", planner::PlannerConfig{});
  ASSERT_TRUE(planned.ok()) << planned.error().to_string();
  ExtrusionRunOptions o;
  o.dt_s = 5e-4;  // coarser than the bench's 0.2 ms: the sweep below runs 13 prints
  const ExtrusionResult off = run_extrusion(planned.value(), o);
  ASSERT_GT(off.error_mm3, 0.0);
  EXPECT_EQ(off.final_motor_mm, off.final_nominal_mm);
  double best_k = 0.0, best = off.error_mm3;
  for (double k = 0.05; k <= 0.601; k += 0.05) {
    o.advance_s = k;
    const ExtrusionResult r = run_extrusion(planned.value(), o);
    EXPECT_EQ(r.final_motor_mm, r.final_nominal_mm) << k;  // no step lost or added at rest
    EXPECT_NEAR(r.commanded_mm3, off.commanded_mm3, 1e-9 * off.commanded_mm3);
    if (r.error_mm3 < best) {
      best = r.error_mm3;
      best_k = k;
    }
  }
  std::printf(
      "extruded-volume error: off %.3f mm^3, K = %.2f s: %.3f mm^3 (ratio %.3f), commanded %.1f "
      "mm^3\n",
      off.error_mm3, best_k, best, best / off.error_mm3, off.commanded_mm3);
  EXPECT_GT(best_k, 0.0);
  EXPECT_LT(best_k, 0.6);  // a minimum inside the sweep, not at its edge
  EXPECT_LE(best / off.error_mm3, 0.5);
}

}  // namespace
}  // namespace feedloop::sim
