// The machine with heaters in virtual time: M190/M109 wait on the machine clock (seconds of heating
// in milliseconds of wall time), the status shows the temperatures, and a thermal fault during a
// wait stops the machine with the heater's message.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <limits>
#include <mutex>
#include <regex>
#include <string>
#include <thread>

#include "config/config.hpp"
#include "core/clock.hpp"
#include "engine/executor_factory.hpp"
#include "engine/machine.hpp"
#include "engine/mcu_heater_link.hpp"
#include "engine/simulated_printer.hpp"
#include "engine/thermal_config.hpp"
#include "gcode/parser.hpp"
#include "sim/thermal_plant.hpp"

namespace feedloop::engine {
namespace {

// VirtualClock's time (advances only when someone sleeps, as fast as the CPU allows) with a gate:
// a sleep past gate_ns holds its thread until the gate is opened, so a test can act at a virtual
// instant whatever the machine's threads' pace on a loaded CPU.
class GatedClock final : public Clock {
 public:
  explicit GatedClock(int64_t start_ns) : now_ns_(start_ns) {}
  int64_t now_ns() const override { return now_ns_.load(std::memory_order_acquire); }
  void sleep_until_ns(int64_t deadline_ns) override {
    {
      std::unique_lock lock(mu_);
      cv_.wait(lock, [&] { return deadline_ns <= gate_ns_; });
    }
    int64_t now = now_ns_.load(std::memory_order_relaxed);
    while (deadline_ns > now &&
           !now_ns_.compare_exchange_weak(now, deadline_ns, std::memory_order_acq_rel)) {
    }
  }
  bool is_virtual() const override { return true; }
  void close_gate_at(int64_t ns) {
    std::lock_guard lock(mu_);
    gate_ns_ = ns;
  }
  void open_gate() {
    {
      std::lock_guard lock(mu_);
      gate_ns_ = std::numeric_limits<int64_t>::max();
    }
    cv_.notify_all();
  }

 private:
  std::atomic<int64_t> now_ns_;
  std::mutex mu_;
  std::condition_variable cv_;
  int64_t gate_ns_ = std::numeric_limits<int64_t>::max();
};

struct MachineRig {
  GatedClock clock{1'000'000'000};
  std::unique_ptr<Machine> m;
  std::atomic<uint64_t> done{0}, failed{0};
  std::string last_failure, last_report;
  std::mutex mu;
  uint64_t ticket = 0;
  explicit MachineRig(config::MachineConfig cfg = config::default_config()) {
    cfg.planner.allow_moves_before_homing = true;  // moves without G28 (docs/homing.md)
    auto ex = make_executor(cfg);
    // Heaters named on a motion MCU: through its session in the executor's bridge (as the daemon).
    const SharedHeaterPorts* ports = ex.value()->heater_ports();
    m = std::make_unique<Machine>(machine_options(cfg), clock, std::move(ex.value()));
    m->set_thermal(std::move(make_thermal_loop(cfg, ports).value()));
    m->set_done_callback([this](CommandDone d) {
      if (!d.report.empty()) {
        std::lock_guard lock(mu);
        last_report = d.report;
      }
      if (!d.status.ok()) {
        std::lock_guard lock(mu);
        last_failure = d.status.error().message;
        failed.fetch_add(1);
      }
      done.fetch_add(1);
    });
  }
  void run(std::initializer_list<const char*> lines) {
    for (const char* l : lines) {
      auto cmd = gcode::parse_line(l, SourceLocation{"t", static_cast<int>(ticket) + 1, 0});
      ASSERT_TRUE(cmd.ok()) << l;
      while (!m->try_submit(++ticket, cmd.value()))
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (done.load() < ticket && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
};

TEST(ThermalMachine, M190AndM109WaitOnTheMachineClockAndSettle) {
  MachineRig r;
  ASSERT_TRUE(r.m->start().ok());
  const auto wall0 = std::chrono::steady_clock::now();
  r.run(
      {"M140 S60", "M104 S215", "M190 S60", "M109 S215", "M106 S128", "G1 X10 Y10 F3000", "M400"});
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  const double virt_s = seconds_from_ns(r.clock.now_ns()) - 1.0;
  const MachineStatus s = r.m->status();
  const ServoStatus servo = r.m->servo_status();
  r.m->stop();
  // The wait advanced the virtual clock while the servo thread idled: no cycle counts it as late.
  EXPECT_EQ(servo.deadline_misses, 0u);
  EXPECT_GT(servo.cycles, 100u);  // the move ran
  std::printf("heat-up: %.1f s of machine time in %.2f s wall; T %.2f B %.2f\n", virt_s, wall_s,
              s.hotend_c, s.bed_c);
  EXPECT_EQ(r.done.load(), r.ticket);
  EXPECT_EQ(r.failed.load(), 0u) << r.last_failure;
  // The bed needs about a minute (250 W on 350 J/K) and 10 s of residency within 1 C.
  EXPECT_GT(virt_s, 40.0);
  EXPECT_LT(virt_s, 300.0);
  EXPECT_NEAR(s.bed_c, 60.0, 2.0);
  EXPECT_NEAR(s.hotend_c, 215.0, 3.0);
  ASSERT_EQ(s.num_heaters, 2);
  EXPECT_STREQ(s.heaters[0].name, "extruder");
  EXPECT_EQ(s.heaters[0].target_c, 215.0);
  ASSERT_EQ(s.num_fans, 2);
  EXPECT_NEAR(s.fans[0].speed, 128.0 / 255.0, 1e-9);  // the kick-start (0.1 s) is over
  EXPECT_EQ(s.fans[1].speed, 1.0);                    // the hotend fan: the extruder is above 50 C
  EXPECT_EQ(std::string(s.temp_report).rfind("T:", 0), 0u) << s.temp_report;
}

// One board for motion and heaters (the extruder and the fans on the toolhead's mcu_e, the bed on
// mcu_z): the servo thread carries the heater messages on those MCUs' sessions, the thermal thread
// runs the loop, the waits and the move as on heater boards of their own.
TEST(ThermalMachine, HeatersOnTheMotionMcusHeatWaitAndMoveOnTheMachinesThreads) {
  config::MachineConfig cfg = config::default_config();
  for (config::HeaterConfig& h : cfg.heaters)
    h.mcu = h.kind == config::HeaterKind::bed ? "mcu_z" : "mcu_e";
  for (config::FanConfig& f : cfg.fans) f.mcu = "mcu_e";
  MachineRig r(cfg);
  ASSERT_TRUE(r.m->start().ok());
  r.run(
      {"M140 S50", "M104 S180", "M190 S50", "M109 S180", "M106 S128", "G1 X10 Y10 F3000", "M400"});
  const double virt_s = seconds_from_ns(r.clock.now_ns()) - 1.0;
  const MachineStatus s = r.m->status();
  r.m->stop();
  std::printf("heaters on the motion MCUs: %.1f s of machine time; T %.2f B %.2f\n", virt_s,
              s.hotend_c, s.bed_c);
  EXPECT_EQ(r.done.load(), r.ticket);
  EXPECT_EQ(r.failed.load(), 0u) << r.last_failure;
  EXPECT_NEAR(s.bed_c, 50.0, 2.0);
  EXPECT_NEAR(s.hotend_c, 180.0, 4.0);
  EXPECT_NE(s.state, MachineState::kEmergencyStopped);
  ASSERT_EQ(s.num_fans, 2);
  EXPECT_NEAR(s.fans[0].speed, 128.0 / 255.0, 1e-9);
  auto* link = dynamic_cast<McuHeaterLink*>(&r.m->thermal()->link());
  ASSERT_NE(link, nullptr);
  ASSERT_EQ(link->mcu_count(), 2);
  EXPECT_NE(link->shared(0), nullptr);  // no session of its own: the bridge's
  EXPECT_GT(link->shared(1)->last_heard_s(),
            virt_s);  // the toolhead board heard lately (host time)
}

// Klipper's min_extrude_temp, Marlin's cold extrusion prevention: with the hotend cold, a move
// that extrudes and a retraction are refused whole (nothing moves, E stays), a travel move is
// not; once the hotend is hot (M109), the same move runs; M302 P1 allows cold extrusion and
// M302 S sets the minimum.
TEST(ThermalMachine, ColdExtrusionIsRefusedWholeUntilTheHotendIsHot) {
  MachineRig r;
  ASSERT_TRUE(r.m->start().ok());
  r.run({"G1 X5 E1 F3000"});  // before the hotend's first report
  EXPECT_EQ(r.failed.load(), 1u);
  EXPECT_NE(r.last_failure.find("extruder has no temperature reading yet"), std::string::npos)
      << r.last_failure;
  r.run({"G4 P1000", "G1 X10 F3000", "G1 X20 E2 F3000", "G10", "M400"});
  MachineStatus s = r.m->status();
  EXPECT_EQ(r.failed.load(), 3u);
  EXPECT_NE(r.last_failure.find("Extrude below minimum temp: extruder is at 2"), std::string::npos)
      << r.last_failure;
  EXPECT_NE(r.last_failure.find("min_extrude_temp is 170 C"), std::string::npos) << r.last_failure;
  EXPECT_DOUBLE_EQ(s.pos_mm[0], 10.0);  // the travel ran, the refused move did not
  EXPECT_DOUBLE_EQ(s.pos_mm[3], 0.0);
  // The status says so too (a print job's pause retracts only when it would pass).
  EXPECT_DOUBLE_EQ(s.min_extrude_temp_c, 170.0);
  EXPECT_FALSE(can_extrude(s));
  r.run({"M302 P1", "M400"});
  s = r.m->status();
  EXPECT_DOUBLE_EQ(s.min_extrude_temp_c, 0.0);
  EXPECT_TRUE(can_extrude(s));
  r.run({"M302 S20", "M302 P0", "M400"});
  s = r.m->status();
  EXPECT_DOUBLE_EQ(s.min_extrude_temp_c, 20.0);
  EXPECT_TRUE(can_extrude(s)) << s.hotend_c;
  r.run({"M302 S20", "G1 X20 E2 F3000", "M302 S170", "G1 X30 E3", "M302 P1", "G1 X40 E4", "M302 P0",
         "M400"});
  s = r.m->status();
  EXPECT_EQ(r.failed.load(), 4u) << r.last_failure;  // only the X30 move, at 170 C again
  EXPECT_DOUBLE_EQ(s.pos_mm[0], 40.0);
  EXPECT_DOUBLE_EQ(s.pos_mm[3], 4.0);
  r.run({"G1 X50 E5", "M109 S200", "G1 X60 E6", "M400"});
  s = r.m->status();
  r.m->stop();
  EXPECT_EQ(r.failed.load(), 5u) << r.last_failure;  // X50 cold after M302 P0; X60 hot
  EXPECT_DOUBLE_EQ(s.pos_mm[0], 60.0);
  EXPECT_DOUBLE_EQ(s.pos_mm[3], 6.0);
  EXPECT_GE(s.hotend_c, 170.0);
  EXPECT_TRUE(can_extrude(s));
}

// Marlin's M108 (break and continue): an M109 waiting for its temperature ends at once, the target
// kept (the heater goes on heating), with a word; the next command runs. An M108 that came before
// a wait does not end it.
TEST(ThermalMachine, M108EndsAHeaterWaitAndKeepsItsTarget) {
  MachineRig r;
  ASSERT_TRUE(r.m->start().ok());
  r.m->break_heater_wait();  // before any wait: not for the next one
  auto m109 = gcode::parse_line("M109 S215", SourceLocation{"t", 1, 0});
  ASSERT_TRUE(m109.ok());
  // Break it part-way up (the heat-up takes tens of seconds of machine time): the machine's
  // threads are held at 30 s of machine time from now, the M108 comes, and they go on.
  const int64_t gate_ns = r.clock.now_ns() + 30'000'000'000;
  r.clock.close_gate_at(gate_ns);
  ASSERT_TRUE(r.m->try_submit(++r.ticket, m109.value()));
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (r.clock.now_ns() < gate_ns - 50'000'000 && r.done.load() < r.ticket &&
         std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::microseconds(100));
  ASSERT_EQ(r.done.load(), 0u) << "the M109 ended before the M108: the earlier M108 ended it";
  const double at_break_c = r.m->status().hotend_c;
  std::printf("M108 at %.1f C\n", at_break_c);
  r.m->break_heater_wait();
  r.clock.open_gate();
  while (r.done.load() < r.ticket && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::microseconds(100));
  const MachineStatus s = r.m->status();
  ASSERT_EQ(r.done.load(), 1u);
  EXPECT_EQ(r.failed.load(), 0u) << r.last_failure;
  EXPECT_GE(at_break_c, 50.0);  // heating: the room is 22 C
  EXPECT_GE(s.hotend_c, at_break_c - 1.0);
  EXPECT_LT(s.hotend_c, 200.0);  // not at its temperature: the wait was cut short
  EXPECT_DOUBLE_EQ(s.hotend_target_c, 215.0);
  EXPECT_NE(r.last_report.find("echo:M109 wait ended by M108 at "), std::string::npos)
      << r.last_report;
  EXPECT_NE(r.last_report.find("(target 215 C kept)"), std::string::npos) << r.last_report;
  r.run({"G1 X10 F3000", "M400"});
  EXPECT_EQ(r.failed.load(), 0u) << r.last_failure;
  r.m->stop();
}

TEST(ThermalMachine, AFaultDuringAWaitStopsTheMachineWithTheHeatersMessage) {
  MachineRig r;
  ASSERT_TRUE(r.m->start().ok());
  r.run({"M104 S200", "M140 S50"});
  sim::ThermalPlant* plant = simulated_thermal_plant(r.m->thermal()->link(), 0);
  ASSERT_NE(plant, nullptr);
  plant->inject(seconds_from_ns(r.clock.now_ns()), sim::ThermalFaultKind::kThermistorOpen);
  r.run({"M190 S50", "G1 X10 F3000"});
  const MachineStatus s = r.m->status();
  r.m->stop();
  EXPECT_EQ(s.state, MachineState::kEmergencyStopped);
  EXPECT_NE(std::string(s.last_error).find("heater extruder: sensor open"), std::string::npos)
      << s.last_error << " / " << r.last_failure;
  EXPECT_EQ(r.failed.load(), 2u);  // the wait and the move after it
  for (int i = 0; i < s.num_heaters; ++i) {
    EXPECT_EQ(s.heaters[i].target_c, 0.0);
    EXPECT_EQ(s.heaters[i].power, 0.0);
  }
  EXPECT_EQ(plant->duty(), 0.0);
}

TEST(ThermalMachine, M303AutotunesTheExtruderAndUsesTheResult) {
  MachineRig r;
  ASSERT_TRUE(r.m->start().ok());
  r.run({"M303 E0 S200 C5 U1"});
  // Marlin's report (OctoPrint reads the #define lines), then the values as the config writes them.
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      r.last_report, m,
      std::regex(R"(^PID Autotune finished! Put the last Kp, Ki and Kd constants from below into )"
                 R"(Configuration.h\n#define DEFAULT_Kp ([0-9.]+)\n#define DEFAULT_Ki ([0-9.]+)\n)"
                 R"(#define DEFAULT_Kd ([0-9.]+)\n// heaters\.extruder\.pid: \{kp: ([0-9.]+), )"
                 R"(ki: ([0-9.]+), kd: ([0-9.]+)\} \(in use until a restart)")))
      << r.last_report;
  const double kp = std::stod(m[4]), ki = std::stod(m[5]), kd = std::stod(m[6]);
  EXPECT_NEAR(std::stod(m[1]), kp, 0.006);  // the two forms agree
  EXPECT_NEAR(std::stod(m[2]), ki, 0.006);
  EXPECT_NEAR(std::stod(m[3]), kd, 0.006);
  // Ziegler-Nichols from one relay run: Ti = Tu / 2 and Td = Tu / 8, so Kd Ki = Kp^2 / 4.
  EXPECT_GT(kp, 1.0);
  EXPECT_LT(kp, 200.0);
  EXPECT_NEAR(kd * ki, kp * kp / 4.0, 0.01 * kp * kp / 4.0);
  r.last_report.clear();
  r.run({"M109 S210", "M302"});
  const MachineStatus s = r.m->status();
  r.m->stop();
  EXPECT_EQ(r.failed.load(), 0u) << r.last_failure;
  EXPECT_NEAR(s.hotend_c, 210.0, 3.0);
  EXPECT_EQ(r.last_report, "echo:Cold extrudes are disabled (min temp 170C)");  // Marlin's M302
}

// A fan the machine does not have (a slicer's auxiliary or chamber fan: OrcaSlicer's M106 P2 / P3)
// is ignored with a word, as Marlin ignores it: not a failure that would end a print job.
TEST(ThermalMachine, AFanTheMachineDoesNotHaveIsIgnoredWithAWord) {
  MachineRig r;
  ASSERT_TRUE(r.m->start().ok());
  r.run({"M106 P3 S180"});
  EXPECT_EQ(r.last_report, "echo:no part fan 3: M106 P3 ignored");
  r.last_report.clear();
  r.run({"M107 P2"});
  EXPECT_EQ(r.last_report, "echo:no part fan 2: M107 P2 ignored");
  r.last_report.clear();
  r.run({"M106 S255"});  // the part fan itself: set, nothing to say
  const MachineStatus s = r.m->status();
  r.m->stop();
  EXPECT_EQ(r.failed.load(), 0u) << r.last_failure;
  EXPECT_EQ(r.last_report, "");
  bool part_fan_on = false;
  for (int i = 0; i < s.num_fans; ++i) part_fan_on |= s.fans[i].part && s.fans[i].requested > 0.99;
  EXPECT_TRUE(part_fan_on);
}

}  // namespace
}  // namespace feedloop::engine
