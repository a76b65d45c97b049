// Heaters and fans on the motion MCUs' own links (one board for motion and heaters, the usual
// printer): a heater's `mcu:` names a motion MCU, whose single McuSession (the bridge's, servo
// side) carries the heater messages too, through engine/shared_heater_port.hpp. Here the bridge
// and the thermal loop are stepped in one thread in virtual time (the machine runs them on the
// servo and thermal threads): the extruder on the toolhead's MCU (mcu_e, with the fans), the bed
// on the Z MCU. The heat goes through those MCUs' boards, each fault is caught with its rule's
// message, and a stop of the motion side is a thermal fault with every heater off.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <optional>
#include <string>

#include "config/config.hpp"
#include "drivers/device/heater_board.hpp"
#include "drivers/transport/mock_transport.hpp"
#include "engine/mcu_bridge.hpp"
#include "engine/mcu_heater_link.hpp"
#include "engine/simulated_printer.hpp"
#include "engine/thermal_config.hpp"
#include "sim/thermal_plant.hpp"

namespace feedloop::engine::testing {
namespace {

config::MachineConfig motion_board_config() {
  config::MachineConfig cfg = config::default_config();
  for (config::HeaterConfig& h : cfg.heaters)
    h.mcu = h.kind == config::HeaterKind::bed ? "mcu_z" : "mcu_e";
  for (config::FanConfig& f : cfg.fans) f.mcu = "mcu_e";
  return cfg;
}

int mcu_index(const McuBridge& b, const std::string& name) {
  for (int i = 0; i < b.mcu_count(); ++i)
    if (b.mcu_name(i) == name) return i;
  return -1;
}

struct MotionBoardRig {
  explicit MotionBoardRig(config::MachineConfig c = motion_board_config()) : cfg(std::move(c)) {
    init();
  }
  config::MachineConfig cfg;
  std::unique_ptr<McuBridge> bridge;
  std::unique_ptr<ThermalLoop> loop;
  double t = 0.0, t_fault = -1.0;

  void init() {
    auto b = McuBridge::create(cfg);
    EXPECT_TRUE(b.ok()) << (b.ok() ? "" : b.error().message);
    bridge = std::move(b.value());
    auto l = make_thermal_loop(cfg, bridge->heater_ports());
    EXPECT_TRUE(l.ok()) << (l.ok() ? "" : l.error().message);
    loop = std::move(l.value());
    EXPECT_TRUE(bridge->start(0.0).ok());
    loop->start(0.0);
  }
  McuHeaterLink& link() { return dynamic_cast<McuHeaterLink&>(loop->link()); }
  sim::ThermalPlant& plant(const std::string& mcu, int channel) {
    return *bridge->simulated_heater_board(mcu_index(*bridge, mcu))->plant(channel);
  }
  // The servo side every 2 ms, the thermal loop every 50 ms (as their threads do); the fault, if
  // any (t_fault set).
  std::optional<std::string> run_until(double t_end,
                                       const std::function<bool(double)>& stop = nullptr) {
    for (int k = 1; t < t_end; ++k) {
      t += 0.002;
      bridge->service(t);
      if (k % 25 != 0) continue;
      auto f = loop->step_to(t);
      if (f) {
        t_fault = t;
        return f;
      }
      if (stop && stop(t)) return std::nullopt;
    }
    return std::nullopt;
  }
};

TEST(MotionMcuHeaters, TheHeatGoesThroughTheMotionMcusOwnSessions) {
  MotionBoardRig rig;
  // The config as a user writes it (mcu: a motion MCU) loads back the same.
  const auto back = config::load_config_text(config::to_yaml(rig.cfg), "motion_board.yaml");
  ASSERT_TRUE(back.ok()) << back.error().to_string();
  EXPECT_TRUE(*back == rig.cfg);
  // Two boards, both motion MCUs: no session of the link's own, no heater-only MCU.
  McuHeaterLink& link = rig.link();
  ASSERT_EQ(link.mcu_count(), 2);
  ASSERT_NE(link.shared(0), nullptr);
  ASSERT_NE(link.shared(1), nullptr);
  EXPECT_EQ(link.shared(0)->mcu_name(), "mcu_z");  // file order of mcus: x y z e
  EXPECT_EQ(link.shared(1)->mcu_name(), "mcu_e");
  const int extruder = rig.loop->find_heater('T'), bed = rig.loop->find_heater('B');
  ASSERT_GE(extruder, 0);
  ASSERT_GE(bed, 0);
  ASSERT_TRUE(rig.loop->set_target(extruder, 150.0).ok());
  ASSERT_TRUE(rig.loop->set_target(bed, 50.0).ok());
  ASSERT_TRUE(rig.loop->set_fan(0, 0.5, rig.t).ok());
  double max_report_error_c = 0.0;  // the host's reading against the plant's sensor
  const auto f = rig.run_until(60.0, [&](double t) {
    if (t > 1.0)  // after the first reports
      max_report_error_c =
        std::max(max_report_error_c, std::fabs(rig.loop->temp_c(extruder) -
                                               rig.plant("mcu_e", 0).sensor_temp_c()));
    return false;
  });
  ASSERT_FALSE(f) << *f;
  const double e_c = rig.plant("mcu_e", 0).block_temp_c(), b_c = rig.plant("mcu_z", 0).block_temp_c();
  std::printf("after 60 s through the motion MCUs: extruder %.1f C (host %.1f), bed %.1f C (host %.1f); "
              "host vs plant sensor max %.2f C\n",
              e_c, rig.loop->temp_c(extruder), b_c, rig.loop->temp_c(bed), max_report_error_c);
  EXPECT_NEAR(rig.loop->temp_c(extruder), 150.0, 3.0);  // settled (the heater takes ~30 s)
  EXPECT_GT(b_c, 35.0);                                 // on its way (the bed takes minutes)
  // The reports are the plant's sensor, at most a report period (0.3 s) of heating behind.
  EXPECT_LT(max_report_error_c, 6.0);
  // The part fan's command reached the toolhead board.
  EXPECT_NEAR(rig.bridge->simulated_heater_board(mcu_index(*rig.bridge, "mcu_e"))->fan(0)->duty(), 0.5,
              0.01);
  // Each port knows its MCU's clock (the configure messages were rescaled to it), and the motion
  // sessions stayed healthy with the heater traffic on them.
  EXPECT_EQ(link.shared(1)->clock_hz(), rig.cfg.mcus[3].clock_hz);
  EXPECT_FALSE(rig.bridge->fault());
  EXPECT_EQ(rig.bridge->faults(), 0u);
  EXPECT_EQ(link.shared(0)->dropped() + link.shared(1)->dropped(), 0u);
}

TEST(MotionMcuHeaters, AnOpenThermistorOnTheToolheadBoardIsCaughtWithinASecond) {
  MotionBoardRig rig;
  const int extruder = rig.loop->find_heater('T');
  ASSERT_TRUE(rig.loop->set_target(extruder, 120.0).ok());
  ASSERT_FALSE(rig.run_until(10.0));
  rig.plant("mcu_e", 0).inject(rig.t, sim::ThermalFaultKind::kThermistorOpen);
  const double t_inject = rig.t;
  const auto f = rig.run_until(t_inject + 5.0);
  ASSERT_TRUE(f) << "no fault";
  EXPECT_NE(f->find("heater extruder: sensor open"), std::string::npos) << *f;
  EXPECT_LE(rig.t_fault - t_inject, 1.0);
  rig.run_until(rig.t + 0.1);  // the off command reaches the board
  EXPECT_EQ(rig.plant("mcu_e", 0).duty(), 0.0);
}

TEST(MotionMcuHeaters, AStopOfTheMotionSideIsAThermalFaultWithEveryHeaterOff) {
  MotionBoardRig rig;
  const int extruder = rig.loop->find_heater('T'), bed = rig.loop->find_heater('B');
  ASSERT_TRUE(rig.loop->set_target(extruder, 120.0).ok());
  ASSERT_TRUE(rig.loop->set_target(bed, 50.0).ok());
  ASSERT_FALSE(rig.run_until(8.0));
  ASSERT_GT(rig.plant("mcu_e", 0).duty(), 0.0);
  ASSERT_GT(rig.plant("mcu_z", 0).duty(), 0.0);
  // The Z board's cable pulled: the bridge stops every MCU; the toolhead's stop turns its heater
  // off on the board, and the thermal loop says why.
  rig.bridge->mock(mcu_index(*rig.bridge, "mcu_z"))->unplug();
  const double t_unplug = rig.t;
  const auto f = rig.run_until(t_unplug + 5.0);
  ASSERT_TRUE(f) << "no fault";
  std::printf("fault %.2f s after the unplug: %s\n", rig.t_fault - t_unplug, f->c_str());
  EXPECT_NE(f->find("mcu_z"), std::string::npos) << *f;
  EXPECT_NE(f->find("a stopped MCU turns its heaters off"), std::string::npos) << *f;
  EXPECT_LT(rig.t_fault - t_unplug, 2.0);
  rig.run_until(rig.t + 0.1);
  EXPECT_EQ(rig.plant("mcu_e", 0).duty(), 0.0);  // stopped by the MCU itself
  // The unplugged board's heater: off by the board's own 3 s rule (no confirmation arrives).
  for (const double t_end = rig.t + 3.5; rig.t < t_end;) rig.bridge->service(rig.t += 0.002);
  EXPECT_EQ(rig.plant("mcu_z", 0).duty(), 0.0);
}

TEST(MotionMcuHeaters, TheMotionMcuTurnsItsHeaterOffWhenTheHostsConfirmationsStop) {
  MotionBoardRig rig;
  const int extruder = rig.loop->find_heater('T');
  ASSERT_TRUE(rig.loop->set_target(extruder, 120.0).ok());
  ASSERT_FALSE(rig.run_until(8.0));
  rig.link().drop_heater_commands(true);  // lost before the port: the motion link stays up
  const double t_drop = rig.t;
  const auto f = rig.run_until(t_drop + 6.0);
  ASSERT_TRUE(f) << "no fault";
  std::printf("watchdog fault %.2f s after the confirmations stopped: %s\n", rig.t_fault - t_drop,
              f->c_str());
  EXPECT_NE(f->find("heater watchdog"), std::string::npos) << *f;
  EXPECT_GT(rig.t_fault - t_drop, 2.5);  // the 3 s rule, counted from the last confirmation
  EXPECT_LT(rig.t_fault - t_drop, 4.0);
  EXPECT_EQ(rig.plant("mcu_e", 0).duty(), 0.0);
  EXPECT_FALSE(rig.bridge->fault());  // the motion side never noticed
}

// Mixed: the extruder on the toolhead's motion MCU, the bed on a board of its own (heater_mcus).
TEST(MotionMcuHeaters, AMotionMcuAndABoardOfItsOwnHeatSideBySide) {
  config::MachineConfig cfg = motion_board_config();
  config::McuConfig bedboard;
  bedboard.name = "bedboard";
  bedboard.transport = config::TransportType::mock;
  cfg.heater_mcus = {bedboard};
  for (config::HeaterConfig& h : cfg.heaters)
    if (h.kind == config::HeaterKind::bed) h.mcu = "bedboard";
  MotionBoardRig rig(cfg);
  McuHeaterLink& link = rig.link();
  ASSERT_EQ(link.mcu_count(), 2);
  EXPECT_EQ(link.shared(0), nullptr);  // heater_mcus first: its own session
  ASSERT_NE(link.shared(1), nullptr);  // then the motion MCU's port
  const int extruder = rig.loop->find_heater('T'), bed = rig.loop->find_heater('B');
  ASSERT_TRUE(rig.loop->set_target(extruder, 120.0).ok());
  ASSERT_TRUE(rig.loop->set_target(bed, 40.0).ok());
  const auto f = rig.run_until(30.0);
  ASSERT_FALSE(f) << *f;
  EXPECT_GT(rig.loop->temp_c(extruder), 100.0);
  EXPECT_GT(rig.loop->temp_c(bed), 30.0);
  EXPECT_TRUE(link.session(0).ready());
}

TEST(MotionMcuHeaters, WithoutTheBridgesPortsTheThermalLoopIsRefused) {
  const config::MachineConfig cfg = motion_board_config();
  const auto l = make_thermal_loop(cfg);
  ASSERT_FALSE(l.ok());
  EXPECT_NE(l.error().message.find("motion MCU 'mcu_z'"), std::string::npos) << l.error().message;
}

TEST(MotionMcuHeaters, ConfigErrorsNameTheKeyAndTheLine) {
  const std::string base(config::default_config_yaml());
  const std::string at = "    kind: bed                            # M140/M190, reported as B\n";
  ASSERT_NE(base.find(at), std::string::npos);
  // The bed on the Z MCU, the others on no board: each of them is named, with its line.
  std::string y = base;
  y.replace(y.find(at), at.size(), at + "    mcu: mcu_z\n");
  auto errors = config::check_config_text(y, "c.yaml");
  ASSERT_EQ(errors.size(), 3u);  // extruder, part, hotend_fan
  for (const auto& e : errors) {
    EXPECT_NE(e.message.find("names no board (mcu:) while others do"), std::string::npos) << e.message;
    EXPECT_GT(e.where.line, 0);
  }
}

}  // namespace
}  // namespace feedloop::engine::testing
