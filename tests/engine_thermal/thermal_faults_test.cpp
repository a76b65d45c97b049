// Each thermal fault injected into the simulated plant, during the heat-up and at temperature, on
// the extruder and on the bed: caught within its rule's time, every heater off, the message naming
// the heater, the rule and its numbers. Normal heat-ups with fan changes trip nothing.
#include <gtest/gtest.h>

#include <cstdio>
#include <functional>

#include "tests/engine_thermal/thermal_rig.hpp"

namespace feedloop::engine::testing {
namespace {

using sim::ThermalFaultKind;

constexpr double kReport = 0.3;   // one report period (Klipper's REPORT_TIME)
constexpr double kStride = 0.05;  // the rig's step

struct Case {
  int heater;  // 0 extruder, 1 bed
  bool at_temperature;
  ThermalFaultKind fault;
};

std::string name(const ::testing::TestParamInfo<Case>& i) {
  return std::string(i.param.heater == 0 ? "extruder_" : "bed_") +
         (i.param.at_temperature ? "at_temp_" : "heating_") + sim::to_string(i.param.fault);
}

class Fault : public ::testing::TestWithParam<Case> {};

TEST_P(Fault, IsCaughtWithinItsRulesTimeAndTurnsEveryHeaterOff) {
  const Case c = GetParam();
  ThermalRig rig;
  const double target = c.heater == 0 ? 210.0 : 60.0;
  ASSERT_TRUE(rig.loop->set_target(0, c.heater == 0 ? 210.0 : 0.0).ok());
  ASSERT_TRUE(rig.loop->set_target(1, 60.0).ok());
  const auto& prot = rig.loop->spec(c.heater).protection;
  if (c.at_temperature) {
    ASSERT_FALSE(
        rig.run_until(900.0, [&](double t) { return rig.loop->reached(c.heater, false, t); }));
    ASSERT_LT(rig.t, 900.0) << "never reached";
    ASSERT_FALSE(rig.run_until(rig.t + 30.0));
  } else {
    ASSERT_FALSE(rig.run_until(15.0));
    ASSERT_LT(rig.loop->temp_c(c.heater), target - 10.0);
  }
  sim::ThermalPlant& plant = rig.plant(c.heater);
  const double t_inject = rig.t;
  plant.inject(t_inject, c.fault);
  // When the rule's condition began, from the plant's true sensor temperature.
  double t_cond = -1.0;
  const auto f = rig.run_until(t_inject + 400.0, [&](double t) {
    if (t_cond < 0 && c.fault == ThermalFaultKind::kHeaterStuckOn &&
        plant.sensor_temp_c() > prot.max_temp_c)
      t_cond = t;
    if (t_cond < 0 && c.fault == ThermalFaultKind::kHeaterOutOfBlock && c.at_temperature &&
        plant.sensor_temp_c() < target - prot.runaway_hysteresis_c)
      t_cond = t;
    return false;
  });
  ASSERT_TRUE(f.has_value()) << "not caught in 400 s";
  const double dt = rig.t_fault - t_inject;
  const std::string heater = c.heater == 0 ? "heater extruder: " : "heater bed: ";
  EXPECT_EQ(f->rfind(heater, 0), 0u) << *f;
  std::printf("%s %s: caught after %.2f s: %s\n", c.heater == 0 ? "extruder" : "bed",
              sim::to_string(c.fault), dt, f->c_str());
  switch (c.fault) {
    case ThermalFaultKind::kThermistorOpen:
      EXPECT_NE(f->find("sensor open"), std::string::npos) << *f;
      EXPECT_LE(dt, kReport + kStride);
      break;
    case ThermalFaultKind::kThermistorShort:
      EXPECT_NE(f->find("sensor short"), std::string::npos) << *f;
      EXPECT_LE(dt, kReport + kStride);
      break;
    case ThermalFaultKind::kSensorStuck:
      EXPECT_NE(f->find("sensor stuck"), std::string::npos) << *f;
      EXPECT_GE(dt, prot.stuck_period_s - kReport);
      EXPECT_LE(dt, prot.stuck_period_s + 2 * kReport + kStride);
      break;
    case ThermalFaultKind::kHeaterStuckOn:
      EXPECT_NE(f->find("max temperature"), std::string::npos) << *f;
      if (t_cond < 0) {  // a noisy sample crossed before the true temperature did
        EXPECT_GT(plant.sensor_temp_c(), prot.max_temp_c - 2.0);
        t_cond = rig.t_fault;
      }
      EXPECT_LE(rig.t_fault - t_cond, kReport + kStride);  // one sample past max_temp
      break;
    case ThermalFaultKind::kHeaterOutOfBlock:
      if (c.at_temperature) {
        // Marlin's runaway (40 s / 4 C; bed 20 s / 2 C) or Klipper's verify_heater, first.
        EXPECT_TRUE(f->find("thermal runaway") != std::string::npos ||
                    f->find("verify_heater") != std::string::npos)
            << *f;
        ASSERT_GE(t_cond, 0.0);
        // The host sees the mean of a report's samples, one report late at most.
        EXPECT_LE(rig.t_fault - t_cond, prot.runaway_period_s + 2 * kReport + kStride);
      } else {
        // Marlin's watch (gain watch_increase_c per watch_period_s) or verify_heater: at most two
        // watch windows (the one running may still show the gain of before the fault).
        EXPECT_TRUE(f->find("heating failed") != std::string::npos ||
                    f->find("verify_heater") != std::string::npos)
            << *f;
        EXPECT_LE(dt, 2 * prot.watch_period_s + kReport + kStride);
      }
      break;
    case ThermalFaultKind::kNone:
      break;
  }
  // Every heater off: targets 0 and the applied duty 0 on both plants (except a stuck MOSFET),
  // once the SET_HEATER 0s crossed the link (the host's next poll: within one stride).
  rig.loop->step_to(rig.t + kStride);
  HeaterStatus hs[4];
  FanStatus fs[4];
  int nh = 0, nf = 0;
  rig.loop->snapshot(hs, nh, fs, nf);
  for (int i = 0; i < nh; ++i) {
    EXPECT_EQ(hs[i].target_c, 0.0) << i;
    EXPECT_EQ(hs[i].power, 0.0) << i;
    EXPECT_EQ(rig.plant(i).duty(), 0.0) << i;
  }
  EXPECT_FALSE(rig.loop->set_target(0, 200.0).ok());  // refused until M999
}

std::vector<Case> all_cases() {
  std::vector<Case> v;
  for (int h : {0, 1})
    for (bool at : {false, true})
      for (ThermalFaultKind k :
           {ThermalFaultKind::kThermistorOpen, ThermalFaultKind::kThermistorShort,
            ThermalFaultKind::kHeaterOutOfBlock, ThermalFaultKind::kHeaterStuckOn,
            ThermalFaultKind::kSensorStuck})
        v.push_back({h, at, k});
  return v;
}

INSTANTIATE_TEST_SUITE_P(Thermal, Fault, ::testing::ValuesIn(all_cases()), name);

// Marlin's runaway alone (verify_heater off): 40 s after the temperature left the hysteresis band,
// with the message of the brief.
TEST(ThermalRules, MarlinRunawayAloneTripsAt40s) {
  config::MachineConfig cfg = config::default_config();
  cfg.heaters[0].protection.verify_max_error = 0;
  ThermalRig rig(cfg);
  ASSERT_TRUE(rig.loop->set_target(0, 210.0).ok());
  ASSERT_FALSE(rig.run_until(600.0, [&](double t) { return rig.loop->reached(0, false, t); }));
  ASSERT_FALSE(rig.run_until(rig.t + 20.0));
  rig.plant(0).inject(rig.t, ThermalFaultKind::kHeaterOutOfBlock);
  double t_below = -1;
  const auto f = rig.run_until(rig.t + 200.0, [&](double t) {
    if (t_below < 0 && rig.loop->temp_c(0) < 210.0 - 4.0) t_below = t;
    return false;
  });
  ASSERT_TRUE(f);
  EXPECT_NE(f->find("heater extruder: thermal runaway: "), std::string::npos) << *f;
  double below_c = 0, for_s = 0, hyst_c = 0;
  ASSERT_EQ(std::sscanf(
                f->c_str(),
                "heater extruder: thermal runaway: %lf C below target for %lf s (hysteresis %lf C)",
                &below_c, &for_s, &hyst_c),
            3)
      << *f;
  EXPECT_GT(below_c, 4.0);
  EXPECT_NEAR(for_s, 40.0, kReport);
  EXPECT_EQ(hyst_c, 4.0);
  EXPECT_NEAR(rig.t_fault - t_below, 40.0, kReport + kStride);
}

// Klipper's verify_heater alone (Marlin's rules off): the error integral reaches max_error.
TEST(ThermalRules, KlipperVerifyHeaterAloneTripsOnTheErrorIntegral) {
  config::MachineConfig cfg = config::default_config();
  cfg.heaters[0].protection.runaway_period_s = 0;
  cfg.heaters[0].protection.watch_period_s = 0;
  ThermalRig rig(cfg);
  ASSERT_TRUE(rig.loop->set_target(0, 210.0).ok());
  ASSERT_FALSE(rig.run_until(600.0, [&](double t) { return rig.loop->reached(0, false, t); }));
  ASSERT_FALSE(rig.run_until(rig.t + 20.0));
  rig.plant(0).inject(rig.t, ThermalFaultKind::kHeaterOutOfBlock);
  const auto f = rig.run_until(rig.t + 200.0);
  ASSERT_TRUE(f);
  EXPECT_NE(f->find("heater extruder: verify_heater: "), std::string::npos) << *f;
  EXPECT_NE(f->find("(max_error 120.0)"), std::string::npos) << *f;
}

// The MCU turns the heater off by itself 3 s after the host's last confirmation (a hung host).
TEST(ThermalRules, McuTurnsTheHeaterOff3sAfterTheHostWentSilent) {
  ThermalRig rig;
  ASSERT_TRUE(rig.loop->set_target(0, 210.0).ok());
  ASSERT_FALSE(rig.run_until(20.0));
  ASSERT_GT(rig.plant(0).duty(), 0.5);
  const double t_silent = rig.t;
  double t_off = -1;
  for (double t = t_silent; t < t_silent + 5.0; t += 0.01) {  // the device runs, the host does not
    rig.loop->link().advance_to(t);
    if (t_off < 0 && rig.plant(0).duty() == 0.0) t_off = t;
  }
  ASSERT_GE(t_off, 0.0);
  // 3 s after the last confirmation, which came with the last report (at most 0.3 s before).
  EXPECT_GE(t_off - t_silent, 3.0 - kReport - kStride);
  EXPECT_LE(t_off - t_silent, 3.0 + 0.3 / 8 + 0.02);
  const auto f = rig.run_until(rig.t + 5.5);
  ASSERT_TRUE(f);
  EXPECT_NE(f->find("heater extruder: mcu heater watchdog"), std::string::npos) << *f;
}

// No false trip: heat-ups of both heaters to several targets with part-fan changes, different
// noise seeds; the temperatures settle within 1.5 C. (bench/thermal runs 50 and prints margins.)
TEST(ThermalRules, NormalHeatUpsWithFanChangesTripNothing) {
  for (uint64_t seed = 1; seed <= 6; ++seed) {
    ThermalRig rig(config::default_config(), seed);
    const double te = 180.0 + 10.0 * static_cast<double>(seed),
                 tb = 50.0 + 3.0 * static_cast<double>(seed);
    ASSERT_TRUE(rig.loop->set_target(0, te).ok());
    ASSERT_TRUE(rig.loop->set_target(1, tb).ok());
    ASSERT_FALSE(rig.run_until(300.0)) << seed;
    ASSERT_TRUE(rig.loop->set_fan(0, 1.0, rig.t).ok());
    ASSERT_FALSE(rig.run_until(420.0)) << seed;
    ASSERT_TRUE(rig.loop->set_fan(0, 0.35, rig.t).ok());
    ASSERT_FALSE(rig.run_until(540.0)) << seed;
    ASSERT_TRUE(rig.loop->set_fan(0, 0.0, rig.t).ok());
    const auto f = rig.run_until(660.0);
    EXPECT_FALSE(f) << seed << ": " << *f;
    EXPECT_NEAR(rig.loop->temp_c(0), te, 1.5) << seed;
    EXPECT_NEAR(rig.loop->temp_c(1), tb, 1.5) << seed;
  }
}

TEST(ThermalLoopReport, MarlinTemperatureLine) {
  ThermalRig rig;
  ASSERT_TRUE(rig.loop->set_target(0, 210.0).ok());
  ASSERT_TRUE(rig.loop->set_target(1, 60.0).ok());
  ASSERT_FALSE(rig.run_until(30.0));
  const std::string r = rig.loop->marlin_report();
  double t = 0, tt = 0, b = 0, bt = 0;
  int pt = -1, pb = -1;
  ASSERT_EQ(std::sscanf(r.c_str(), "T:%lf /%lf B:%lf /%lf @:%d B@:%d", &t, &tt, &b, &bt, &pt, &pb),
            6)
      << r;
  EXPECT_EQ(tt, 210.0);
  EXPECT_EQ(bt, 60.0);
  EXPECT_GT(t, 60.0);  // 30 s of a 40 W cartridge
  EXPECT_EQ(pt, 127);  // still at full power
  EXPECT_GT(pb, 100);
  // Above max_temp: refused with the limit in the message.
  const Status s = rig.loop->set_target(0, 300.0);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("max_temp_c 285.0"), std::string::npos) << s.error().message;
}

}  // namespace
}  // namespace feedloop::engine::testing
