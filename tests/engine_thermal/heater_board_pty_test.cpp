// A heater board on a real serial line, in real time (issue 16: heaters on an MCU, not only on
// the simulated printer): feedloop-vmcu --heater-board serves the config's heaters and their
// thermal plants on a pseudo-terminal; the daemon's thermal loop reaches it through
// heater_mcus (transport: serial) -> SerialTransport -> McuSession -> frames. The board heats,
// applies Klipper's 3 s re-confirmation rule by itself, and a board that loses power is a
// thermal fault that names it (its reports stop: ThermalLoop's report timeout, 2 s). And one
// board for motion and heaters: the toolhead's motion MCU on the pty drives the heaters too, its
// one session the bridge's (heater messages through engine/shared_heater_port.hpp).
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <thread>

#include "config/config.hpp"
#include "core/clock.hpp"
#include "engine/mcu_bridge.hpp"
#include "engine/mcu_heater_link.hpp"
#include "engine/thermal_config.hpp"
#include "tests/drivers/vmcu_process.hpp"

namespace feedloop::engine {
namespace {

const std::string kVmcu = std::string(FEEDLOOP_BINARY_DIR) + "/drivers/feedloop-vmcu";

struct BoardRig {
  std::filesystem::path dir;
  config::MachineConfig cfg;
  feedloop::testing::VmcuProcess vmcu;
  std::unique_ptr<ThermalLoop> loop;
  MonotonicClock clock;

  // The embedded printer with its heaters and fans on one serial board, `board`.
  explicit BoardRig(const std::string& tag) {
    dir = std::filesystem::temp_directory_path() /
          ("feedloop-heater-board-" + tag + "-" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    cfg = config::default_config();
    config::McuConfig board;
    board.name = "board";
    board.transport = config::TransportType::serial;
    board.serial.device = (dir / "tty").string();
    board.clock_hz = 16000000;
    cfg.heater_mcus = {board};
    for (auto& h : cfg.heaters) h.mcu = "board";
    for (auto& f : cfg.fans) f.mcu = "board";
    const std::string path = (dir / "printer.yaml").string();
    std::ofstream(path) << config::to_yaml(cfg);
    EXPECT_TRUE(vmcu.start(kVmcu, {"--link", board.serial.device, "--name", "board", "--heater-board", path},
                           (dir / "vmcu.log").string()))
        << vmcu.error();
    auto l = make_thermal_loop(cfg);
    EXPECT_TRUE(l.ok()) << (l.ok() ? "" : l.error().message);
    if (l.ok()) loop = std::move(l.value());
    if (loop) loop->start(now_s());
  }
  ~BoardRig() {
    loop.reset();
    vmcu.stop();
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }
  double now_s() const { return seconds_from_ns(clock.now_ns()); }
  McuHeaterLink& link() { return dynamic_cast<McuHeaterLink&>(loop->link()); }
  // Steps the loop every 20 ms (the daemon's thermal thread) until stop() or t_end; the fault.
  std::optional<std::string> run_for(double seconds, const std::function<bool()>& stop = nullptr) {
    const double end = now_s() + seconds;
    while (now_s() < end) {
      if (auto f = loop->step_to(now_s())) return f;
      if (stop && stop()) return std::nullopt;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return std::nullopt;
  }
};

TEST(HeaterBoardPty, TheBoardHeatsAndTurnsItsHeaterOffWhenTheHostStopsConfirming) {
  BoardRig rig("heat");
  ASSERT_TRUE(rig.loop);
  const int extruder = rig.loop->find_heater('T');
  ASSERT_TRUE(rig.loop->set_target(extruder, 100.0).ok());
  ASSERT_FALSE(rig.run_for(1.5)) << "a fault";
  const double start_c = rig.loop->temp_c(extruder);
  // 40 W into 12 J/K, 1 s of delay and 1.5 s of sensor lag: some 8 C in the next 5 s.
  const auto f0 = rig.run_for(5.0);
  ASSERT_FALSE(f0) << *f0;
  const double rise_c = rig.loop->temp_c(extruder) - start_c;
  drivers::McuSession& s = rig.link().session(0);
  EXPECT_TRUE(s.ready());
  EXPECT_EQ(s.mcu_clock_hz(), 16000000u);  // the board's own clock, learned at identification
  EXPECT_GT(rise_c, 4.0) << "the heater did not heat: " << rig.loop->marlin_report();
  std::printf("over the pty: %s (+%.1f C in 5 s)\n", rig.loop->marlin_report().c_str(), rise_c);
  // The host's confirmations stop (lost before the wire, the link up): the board turns the heater
  // off 3 s after the last one by itself, and says so.
  rig.link().drop_heater_commands(true);
  const double t_drop = rig.now_s();
  const auto f = rig.run_for(6.0);
  ASSERT_TRUE(f) << "no fault";
  const double after_s = rig.now_s() - t_drop;
  EXPECT_NE(f->find("heater extruder: mcu heater watchdog: no confirmation from the host for 3.0 s"),
            std::string::npos) << *f;
  // The last confirmation answered the last report (a report period before the drop), less the
  // 20 ms step and a report the scheduler delayed (0.2 s: a busy CI host; 2.85 s seen here).
  EXPECT_GE(after_s, 3.0 - 0.3 - 0.2);
  EXPECT_LE(after_s, 3.0 + 0.5);         // + a sample + the report's way back + the 20 ms step
  std::printf("confirmations dropped: the board's fault after %.2f s: %s\n", after_s, f->c_str());
}

TEST(HeaterBoardPty, ABoardThatLosesPowerIsAThermalFaultNamingIt) {
  BoardRig rig("power");
  ASSERT_TRUE(rig.loop);
  ASSERT_TRUE(rig.loop->set_target(rig.loop->find_heater('B'), 50.0).ok());
  ASSERT_FALSE(rig.run_for(1.5)) << "a fault";
  ASSERT_TRUE(rig.link().session(0).ready());
  rig.vmcu.stop(SIGKILL);  // the board loses power: the pty hangs up
  // ... and its device node goes, as a USB serial's does. Left, the link would name a dead pty
  // whose number the kernel gives the next pty opened (another test's, at ctest -j2): the session
  // reconnects to that one, nothing answers, and its ack timeout (1 s) came before the reports'.
  std::filesystem::remove(rig.dir / "tty");
  const double t_kill = rig.now_s();
  const auto f = rig.run_for(5.0);
  ASSERT_TRUE(f) << "no fault";
  // The reports stop: 2 s after the last one (at most a report period before the kill).
  EXPECT_NE(f->find("no temperature report for 2.0 s (its MCU stopped reporting: MCU 'board'"),
            std::string::npos) << *f;
  EXPECT_NE(f->find("disconnected"), std::string::npos) << *f;  // the session's event
  // Less the 20 ms step and a late report (0.2 s: a busy CI host; 1.73 s seen here, 30 ms from
  // the bare 2.0 - 0.3).
  EXPECT_GE(rig.now_s() - t_kill, 2.0 - 0.3 - 0.2);
  EXPECT_LE(rig.now_s() - t_kill, 2.0 + 0.3);
  std::printf("board killed: thermal fault after %.2f s: %s\n", rig.now_s() - t_kill, f->c_str());
}

// The embedded printer with its toolhead MCU (mcu_e: the extruder's motor) on a serial line,
// driving every heater and fan too; x, y, z stay simulated in-process. The test's thread plays
// the servo thread (the bridge every 1 ms) and the thermal thread (the loop every 20 ms).
struct MotionBoardRig {
  std::filesystem::path dir;
  config::MachineConfig cfg;
  feedloop::testing::VmcuProcess vmcu;
  std::unique_ptr<McuBridge> bridge;
  std::unique_ptr<ThermalLoop> loop;
  MonotonicClock clock;

  MotionBoardRig() {
    dir = std::filesystem::temp_directory_path() /
          ("feedloop-motion-board-" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    cfg = config::default_config();
    config::McuConfig& e = cfg.mcus.back();
    EXPECT_EQ(e.name, "mcu_e");
    e.transport = config::TransportType::serial;
    e.serial.device = (dir / "tty").string();
    for (auto& h : cfg.heaters) h.mcu = "mcu_e";
    for (auto& f : cfg.fans) f.mcu = "mcu_e";
    const std::string path = (dir / "printer.yaml").string();
    std::ofstream(path) << config::to_yaml(cfg);
    EXPECT_TRUE(vmcu.start(
        kVmcu,
        {"--link", e.serial.device, "--name", "mcu_e", "--axis", "3", "--heater-board", path},
        (dir / "vmcu.log").string()))
        << vmcu.error();
    auto b = McuBridge::create(cfg);
    EXPECT_TRUE(b.ok()) << (b.ok() ? "" : b.error().message);
    if (!b.ok()) return;
    bridge = std::move(b.value());
    auto l = make_thermal_loop(cfg, bridge->heater_ports());
    EXPECT_TRUE(l.ok()) << (l.ok() ? "" : l.error().message);
    if (l.ok()) loop = std::move(l.value());
    EXPECT_TRUE(bridge->start(now_s()).ok());
    if (loop) loop->start(now_s());
  }
  ~MotionBoardRig() {
    loop.reset();
    bridge.reset();
    vmcu.stop();
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }
  double now_s() const { return seconds_from_ns(clock.now_ns()); }
  std::optional<std::string> run_for(double seconds) {
    const double end = now_s() + seconds;
    double next_thermal_s = now_s();
    while (now_s() < end) {
      bridge->service(now_s());
      if (now_s() >= next_thermal_s) {
        next_thermal_s += 0.02;
        if (auto f = loop->step_to(now_s())) return f;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    return std::nullopt;
  }
};

TEST(MotionBoardPty, TheToolheadMcuDrivesItsMotorAndItsHeatersOnOneSession) {
  MotionBoardRig rig;
  ASSERT_TRUE(rig.loop);
  const int extruder = rig.loop->find_heater('T');
  ASSERT_TRUE(rig.loop->set_target(extruder, 100.0).ok());
  ASSERT_FALSE(rig.run_for(1.5)) << "a fault";
  const double start_c = rig.loop->temp_c(extruder);
  const auto f0 = rig.run_for(5.0);
  ASSERT_FALSE(f0) << *f0;
  const double rise_c = rig.loop->temp_c(extruder) - start_c;
  const int e = rig.bridge->mcu_of_joint(3);
  ASSERT_GE(e, 0);
  EXPECT_TRUE(rig.bridge->session(e).ready());
  EXPECT_FALSE(rig.bridge->fault());
  EXPECT_TRUE(rig.bridge->ready());  // the motion side is up on the same session
  auto& link = dynamic_cast<McuHeaterLink&>(rig.loop->link());
  ASSERT_EQ(link.mcu_count(), 1);
  ASSERT_NE(link.shared(0), nullptr);
  EXPECT_GT(rise_c, 4.0) << "the heater did not heat: " << rig.loop->marlin_report();
  std::printf("motion MCU on the pty: %s (+%.1f C in 5 s); its session: %llu frames in\n",
              rig.loop->marlin_report().c_str(), rise_c,
              static_cast<unsigned long long>(rig.bridge->session(e).link_stats().delivered));
  // The board loses power: the bridge's session fails, every MCU is stopped, and the thermal loop
  // says which board and why.
  rig.vmcu.stop(SIGKILL);
  const double t_kill = rig.now_s();
  const auto f = rig.run_for(5.0);
  ASSERT_TRUE(f) << "no fault";
  std::printf("toolhead board killed: thermal fault after %.2f s: %s\n", rig.now_s() - t_kill,
              f->c_str());
  EXPECT_NE(f->find("mcu_e"), std::string::npos) << *f;
  EXPECT_LE(rig.now_s() - t_kill, 2.0 + 0.3);
}

}  // namespace
}  // namespace feedloop::engine
