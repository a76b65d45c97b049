// The identification uses the simulator's small-signal FRFs as its measurements (exact frequency
// grid, milliseconds instead of minutes). Check at a few frequencies that this is what a sine
// dwell through real step pulses measures on the same plant (carriage A to A at the centre).
#include <cmath>
#include <cstdio>
#include <numbers>

#include <gtest/gtest.h>

#include "sim/delta_plant.hpp"
#include "sim/linearize.hpp"
#include "sim/sine_dwell.hpp"

namespace feedloop::sim {
namespace {

TEST(DeltaIdentMeasurement, SineDwellThroughStepsMatchesTheLinearisation) {
  auto plant = DeltaPlant::create(DeltaPlantParams{});
  ASSERT_TRUE(plant.ok()) << plant.error().message;
  DeltaPlant& pl = **plant;
  const LinearModel lin = pl.linearize();
  for (const double f_hz : {15.0, 45.0, 90.0}) {
    SineDwellSpec spec;
    spec.freq_hz = f_hz;
    spec.amplitude_mm = 0.1;  // 8 steps of 12.5 um
    spec.center_mm = pl.commanded_rel_mm(0);
    spec.settle_periods = 30;
    spec.measure_periods = 20;
    const std::complex<double> dwell =
        sine_dwell(pl.carriage_port(0), pl.params().mm_per_step, pl.time_s(), spec, [&](double t_s) {
          pl.advance_to(t_s);
          return pl.carriage_rel_mm(0);
        });
    const std::complex<double> small_signal = frequency_response(lin, f_hz)(0, 0);
    const double rel = std::abs(dwell / small_signal - 1.0);
    std::printf("%5.1f Hz: sine dwell %.4f /%.2f deg, linearisation %.4f /%.2f deg, rel diff %.3f %%\n", f_hz,
                std::abs(dwell), std::arg(dwell) * 180 / std::numbers::pi, std::abs(small_signal),
                std::arg(small_signal) * 180 / std::numbers::pi, 100 * rel);
    EXPECT_LT(rel, 0.02);
  }
}

}  // namespace
}  // namespace feedloop::sim
