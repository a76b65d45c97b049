// PID with anti-windup and the relay autotune, on the thermal plant (sim/thermal_plant), whose
// delay, sensor lag, ADC noise and fan cooling the controller does not model.
#include <gtest/gtest.h>

#include <cmath>

#include "sim/thermal_plant.hpp"
#include "thermal/autotune.hpp"
#include "thermal/pid.hpp"

namespace feedloop::thermal {
namespace {

struct HeatRun {
  double overshoot_c = 0, settle_s = -1, final_c = 0, max_err_after_settle_c = 0;
};

// Closed loop at 0.3 s reports (Klipper's REPORT_TIME).
HeatRun heat(sim::ThermalPlant& plant, HeaterPid& pid, double target_c, double duration_s,
             double fan_at_s = -1) {
  HeatRun r;
  const auto& s = plant.params().sensor;
  double settled_since = -1;
  for (double t = 0.3; t <= duration_s; t += 0.3) {
    if (fan_at_s >= 0 && std::fabs(t - fan_at_s) < 0.15) plant.set_fan(t, 1.0);
    const double temp = temp_at_adc(s, plant.read_adc(t) / 65535.0);
    plant.set_duty(t, pid.update(t, temp, target_c));
    r.overshoot_c = std::max(r.overshoot_c, plant.block_temp_c() - target_c);
    if (std::fabs(temp - target_c) <= 1.0) {
      if (settled_since < 0) settled_since = t;
      if (r.settle_s < 0 && t - settled_since >= 10.0) r.settle_s = settled_since;
    } else {
      settled_since = -1;
    }
    if (r.settle_s >= 0 && t > r.settle_s + 10.0 &&
        (fan_at_s < 0 || t < fan_at_s || t > fan_at_s + 60))
      r.max_err_after_settle_c = std::max(r.max_err_after_settle_c, std::fabs(temp - target_c));
    r.final_c = temp;
  }
  return r;
}

TEST(Pid, HeatsTheHotendTo210WithLittleOvershootAndHoldsItAgainstTheFan) {
  sim::ThermalPlant plant(sim::ThermalPlantParams{});
  HeaterPid pid(PidParams{22.2, 1.08, 114.0});
  const HeatRun r = heat(plant, pid, 210.0, 400.0, 250.0);
  EXPECT_GE(r.settle_s, 0.0);
  EXPECT_LT(r.settle_s, 150.0);
  EXPECT_LT(r.overshoot_c, 8.0);
  EXPECT_LT(r.max_err_after_settle_c, 2.0);
  EXPECT_NEAR(r.final_c, 210.0, 2.0);  // the integral made up the fan's extra loss
}

TEST(Pid, AntiWindupKeepsTheOvershootOfALongSaturatedHeatUpSmall) {
  // A slow bed: 120 s at full power. Without conditional integration the integral would
  // accumulate ~100 C*s per second of saturation and overshoot by tens of degrees.
  sim::ThermalPlantParams bp;
  bp.power_w = 200;
  bp.heat_capacity_j_k = 600;
  bp.loss_w_k = 1.5;
  bp.fan_loss_w_k = 0.1;
  bp.delay_s = 4;
  bp.sensor_tau_s = 3;
  bp.sensor = *builtin_sensor("EPCOS 100K B57560G104F");
  sim::ThermalPlant plant(bp);
  HeaterPid pid(PidParams{97.1, 1.41, 1675.16});  // Marlin's default bed gains
  const HeatRun r = heat(plant, pid, 60.0, 900.0);
  EXPECT_LT(r.overshoot_c, 3.0);
  EXPECT_NEAR(r.final_c, 60.0, 1.0);
  EXPECT_LE(pid.integral() * 1.41 / 255.0, 1.0 + 1e-9);
}

TEST(Autotune, RelayTuningFindsGainsThatControlThePlant) {
  sim::ThermalPlant plant(sim::ThermalPlantParams{});
  RelayAutotune tune(AutotuneParams{200.0, 5.0, 1.0, 5, 1200.0, 260.0});
  const auto& s = plant.params().sensor;
  double t = 0;
  while (tune.state() == AutotuneState::kRunning && t < 1500) {
    t += 0.3;
    plant.set_duty(t, tune.update(t, temp_at_adc(s, plant.read_adc(t) / 65535.0)));
  }
  ASSERT_EQ(tune.state(), AutotuneState::kDone);
  // The oscillation: a period of tens of seconds (delay + lag), gains of the hotend's magnitude.
  EXPECT_GT(tune.ultimate_period_s(), 5.0);
  EXPECT_LT(tune.ultimate_period_s(), 120.0);
  const PidParams g = tune.result();
  EXPECT_GT(g.kp, 5.0);
  EXPECT_LT(g.kp, 100.0);
  sim::ThermalPlant fresh(sim::ThermalPlantParams{});
  HeaterPid pid(g);
  const HeatRun r = heat(fresh, pid, 210.0, 500.0);
  EXPECT_GE(r.settle_s, 0.0);
  EXPECT_LT(r.overshoot_c, 15.0);
  EXPECT_NEAR(r.final_c, 210.0, 2.0);
}

TEST(Autotune, AbortsAboveItsMaxTemperature) {
  sim::ThermalPlantParams p;
  p.delay_s = 8;  // a long delay: the first overshoot passes max_temp
  sim::ThermalPlant plant(p);
  RelayAutotune tune(AutotuneParams{240.0, 5.0, 1.0, 5, 1200.0, 245.0});
  double t = 0;
  while (tune.state() == AutotuneState::kRunning && t < 1500) {
    t += 0.3;
    plant.set_duty(t, tune.update(t, temp_at_adc(p.sensor, plant.read_adc(t) / 65535.0)));
  }
  EXPECT_EQ(tune.state(), AutotuneState::kTooHot);
}

}  // namespace
}  // namespace feedloop::thermal
