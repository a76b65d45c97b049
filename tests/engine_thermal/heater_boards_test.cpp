// Heaters and fans on the boards of heater_mcus (config/README.md): each board is its own MCU
// session; a heater or fan takes its board's channels in file order, and the thermal loop's
// indices map to them both ways (commands out, reports and faults back). Two simulated boards
// in virtual time here; a board on a real serial line: heater_board_pty_test.cpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>

#include "config/config.hpp"
#include "drivers/device/heater_board.hpp"
#include "engine/mcu_heater_link.hpp"
#include "tests/engine_thermal/thermal_rig.hpp"

namespace feedloop::engine::testing {
namespace {

// The embedded printer with its heaters split over two boards: the extruder and both fans on
// `head` (72 MHz), the bed on `bedboard` (16 MHz), listed in that order.
config::MachineConfig two_board_config() {
  config::MachineConfig cfg = config::default_config();
  config::McuConfig head, bed;
  head.name = "head";
  head.transport = config::TransportType::mock;
  head.clock_hz = 72000000;
  bed.name = "bedboard";
  bed.transport = config::TransportType::mock;
  bed.clock_hz = 16000000;
  cfg.heater_mcus = {head, bed};
  for (config::HeaterConfig& h : cfg.heaters) h.mcu = h.kind == config::HeaterKind::bed ? "bedboard" : "head";
  for (config::FanConfig& f : cfg.fans) f.mcu = "head";
  return cfg;
}

TEST(HeaterBoards, TwoBoardsEachDriveTheirOwnHeatersOnTheirOwnClocks) {
  const config::MachineConfig cfg = two_board_config();
  // The config as a user writes it loads back the same (heater_mcus and each mcu: key).
  const auto back = config::load_config_text(config::to_yaml(cfg), "two_boards.yaml");
  ASSERT_TRUE(back.ok()) << back.error().to_string();
  EXPECT_TRUE(*back == cfg);

  ThermalRig rig(cfg);
  auto& link = dynamic_cast<McuHeaterLink&>(rig.loop->link());
  ASSERT_EQ(link.mcu_count(), 2);
  const int extruder = rig.loop->find_heater('T'), bed = rig.loop->find_heater('B');
  ASSERT_GE(extruder, 0);
  ASSERT_GE(bed, 0);
  EXPECT_EQ(link.heater_route(extruder).mcu, 0);
  EXPECT_EQ(link.heater_route(bed).mcu, 1);
  EXPECT_EQ(link.heater_route(bed).local, 0);  // the bed board's first channel
  ASSERT_TRUE(rig.loop->set_target(extruder, 200.0).ok());
  ASSERT_TRUE(rig.loop->set_target(bed, 60.0).ok());
  ASSERT_TRUE(rig.loop->set_fan(0, 0.5, rig.t).ok());
  uint16_t bed_board_duty_max = 0;  // what the bed's board applied on its channel 0
  ASSERT_FALSE(rig.run_until(400.0, [&](double t) {
    bed_board_duty_max = std::max(bed_board_duty_max, link.sim(1)->board().heater(0).duty);
    return rig.loop->reached(extruder, false, t) && rig.loop->reached(bed, false, t);
  })) << "a fault";
  EXPECT_LT(rig.t, 399.0) << "not both settled";
  // Each board identified with its own clock, and each plant heated by its own board.
  EXPECT_EQ(link.session(0).mcu_clock_hz(), 72000000u);
  EXPECT_EQ(link.session(1).mcu_clock_hz(), 16000000u);
  EXPECT_NEAR(rig.plant(extruder).sensor_temp_c(), 200.0, 3.0);
  EXPECT_NEAR(rig.plant(bed).sensor_temp_c(), 60.0, 2.0);
  EXPECT_TRUE(link.sim(0)->board().heater(0).configured);
  EXPECT_FALSE(link.sim(0)->board().heater(1).configured);  // the bed is not on the head board
  EXPECT_TRUE(link.sim(1)->board().heater(0).configured);
  EXPECT_GT(bed_board_duty_max, 60000u);  // full power while heating
  EXPECT_GT(link.sim(1)->board().heater(0).last_adc, 0u);
  ASSERT_NE(simulated_part_fan(link, 0), nullptr);
  EXPECT_NEAR(simulated_part_fan(link, 0)->duty(), 0.5, 0.01);
  std::printf("two boards: extruder %.1f C (head, 72 MHz), bed %.1f C (bedboard, 16 MHz) at %.0f s\n",
              rig.loop->temp_c(extruder), rig.loop->temp_c(bed), rig.t);
}

// A fault on the bed's board names the bed: the report's channel maps back to the loop's heater.
TEST(HeaterBoards, AFaultOnTheSecondBoardNamesItsHeater) {
  ThermalRig rig(two_board_config());
  const int bed = rig.loop->find_heater('B');
  ASSERT_TRUE(rig.loop->set_target(bed, 60.0).ok());
  ASSERT_FALSE(rig.run_until(10.0));
  rig.plant(bed).inject(rig.t, sim::ThermalFaultKind::kThermistorOpen);
  const double t_inject = rig.t;
  const auto f = rig.run_until(t_inject + 5.0);
  ASSERT_TRUE(f) << "no fault";
  EXPECT_NE(f->find("heater bed: sensor open"), std::string::npos) << *f;
  EXPECT_LE(rig.t_fault - t_inject, 1.0);
  EXPECT_EQ(rig.plant(bed).duty(), 0.0);
}

TEST(HeaterBoards, ConfigErrorsNameTheKeyAndTheLine) {
  const std::string base(config::default_config_yaml());
  // A heater naming a board that is not listed.
  std::string y = base;
  const std::string at = "    kind: bed                            # M140/M190, reported as B\n";
  ASSERT_NE(y.find(at), std::string::npos);
  y.replace(y.find(at), at.size(), at + "    mcu: nowhere\n");
  auto errors = config::check_config_text(y, "c.yaml");
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_NE(errors[0].message.find("heaters.bed.mcu: no MCU named 'nowhere'"), std::string::npos)
      << errors[0].message;
  EXPECT_GT(errors[0].where.line, 0);
  // heater_mcus given: every heater and fan must name its board.
  y = base + "heater_mcus:\n  - {name: board, transport: serial, serial: {device: /dev/ttyACM9}}\n";
  errors = config::check_config_text(y, "c.yaml");
  EXPECT_EQ(errors.size(), 4u);  // extruder, bed, part, hotend_fan
  for (const auto& e : errors) EXPECT_NE(e.message.find("mcu"), std::string::npos) << e.message;
  // A board's name may not repeat a motion MCU's.
  y = base + "heater_mcus:\n  - {name: mcu_x, transport: mock}\n";
  errors = config::check_config_text(y, "c.yaml");
  ASSERT_GE(errors.size(), 1u);
  bool clash = false;
  for (const auto& e : errors) clash = clash || e.message.find("already names an mcu") != std::string::npos;
  EXPECT_TRUE(clash) << errors[0].message;
}

}  // namespace
}  // namespace feedloop::engine::testing
