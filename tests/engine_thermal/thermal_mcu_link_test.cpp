// Heaters through the MCU link (issue 16, "on the MCU side"): the thermal loop reaches the
// simulated printer's heater MCU only through McuSession frames (engine/mcu_heater_link.hpp ->
// mock transport -> VirtualMcu -> HeaterBoard -> thermal plant). The MCU's own rules hold with the
// host silent: Klipper's 3 s re-confirmation (MAX_HEAT_TIME) and its max-temp limit; the host then
// names the heater and the rule. A v2 MCU is refused with a message.
#include <gtest/gtest.h>

#include <cstdio>

#include "drivers/device/heater_board.hpp"
#include "drivers/device/virtual_mcu.hpp"
#include "drivers/transport/mock_transport.hpp"
#include "engine/mcu_heater_link.hpp"
#include "tests/engine_thermal/thermal_rig.hpp"

namespace feedloop::engine::testing {
namespace {

constexpr double kReport = 0.3;        // Klipper's REPORT_TIME
constexpr double kSample = 0.3 / 8;    // one ADC sample (8 per report)
constexpr double kStride = 0.05;       // the rig's step
constexpr double kConfirm = 3.0;       // Klipper's MAX_HEAT_TIME

McuHeaterLink& mcu_link(ThermalRig& rig) { return dynamic_cast<McuHeaterLink&>(rig.loop->link()); }

// The heat-up goes through frames: the session identified the heater MCU at protocol v3, the
// reports came back in frames, and the heater MCU runs on its own clock (72 MHz, not the host's).
TEST(ThermalMcuLink, HeatUpRunsThroughTheSessionsFrames) {
  ThermalRig rig;
  ASSERT_TRUE(rig.loop->set_target(0, 210.0).ok());
  ASSERT_FALSE(rig.run_until(120.0, [&](double t) { return rig.loop->reached(0, false, t); }));
  McuHeaterLink& link = mcu_link(rig);
  ASSERT_EQ(link.mcu_count(), 1);
  drivers::McuSession& s = link.session(0);
  EXPECT_TRUE(s.ready());
  EXPECT_EQ(s.negotiated_version(), protocol::kProtocolVersion);
  EXPECT_EQ(s.mcu_clock_hz(), static_cast<uint32_t>(rig.cfg.stepgen.mcu_clock_hz));
  const double t = rig.t;
  // A report every 0.3 s each way for two heaters, plus SET_HEATERs: hundreds of frames.
  EXPECT_GT(s.link_stats().delivered, static_cast<uint64_t>(2 * t / kReport));
  EXPECT_GT(link.mock(0)->stats().frames, static_cast<uint64_t>(4 * t / kReport));
  EXPECT_NEAR(rig.loop->temp_c(0), 210.0, rig.loop->spec(0).hysteresis_c);  // settled (M109's test)
  std::printf("heat-up over the link: %.1f C at %.1f s, %llu payloads delivered to the host\n",
              rig.loop->temp_c(0), t, static_cast<unsigned long long>(s.link_stats().delivered));
}

// The host's confirmations stop (its SET_HEATERs are lost before the wire, the link stays up):
// the MCU turns the heater off 3 s after the last one, and the host names the heater and the rule.
TEST(ThermalMcuLink, McuTurnsTheHeaterOffWhenConfirmationsStop) {
  ThermalRig rig;
  ASSERT_TRUE(rig.loop->set_target(0, 210.0).ok());
  ASSERT_FALSE(rig.run_until(20.0));
  ASSERT_GT(rig.plant(0).duty(), 0.5);
  const double t_drop = rig.t;
  mcu_link(rig).drop_heater_commands(true);
  double t_off = -1;
  const auto f = rig.run_until(t_drop + 10.0, [&](double t) {
    if (t_off < 0 && rig.plant(0).duty() == 0.0) t_off = t;
    return false;
  });
  ASSERT_TRUE(f) << "no fault";
  ASSERT_GE(t_off, 0.0);
  EXPECT_NE(f->find("heater extruder: mcu heater watchdog: no confirmation from the host for 3.0 s"),
            std::string::npos) << *f;
  EXPECT_NE(f->find("(detected by the MCU)"), std::string::npos) << *f;
  // The last confirmation answered the last report (at most one report before t_drop): off 3 s
  // after it, at the next ADC sample; the host knows within one stride more.
  EXPECT_GE(t_off - t_drop, kConfirm - kReport - kStride);
  EXPECT_LE(t_off - t_drop, kConfirm + kSample + kStride);
  EXPECT_LE(rig.t_fault - t_off, kStride + 1e-9);
  EXPECT_GT(mcu_link(rig).set_heater_dropped(), 0u);
  std::printf("confirmations dropped at %.2f s: heater off after %.3f s, host reports after %.3f s: %s\n",
              t_drop, t_off - t_drop, rig.t_fault - t_drop, f->c_str());
}

// The whole host stalls (no session poll, nothing read or sent): the MCU still turns the heater
// off within 3 s + one report, by itself; when the host runs again it reports the MCU's fault.
TEST(ThermalMcuLink, McuTurnsTheHeaterOffDuringAHostStall) {
  ThermalRig rig;
  ASSERT_TRUE(rig.loop->set_target(0, 210.0).ok());
  ASSERT_FALSE(rig.run_until(20.0));
  ASSERT_GT(rig.plant(0).duty(), 0.5);
  const double t_stall = rig.t;
  double t_off = -1;
  for (double t = t_stall; t < t_stall + 6.0; t += 0.01) {
    mcu_link(rig).run_devices_only(t);
    if (t_off < 0 && rig.plant(0).duty() == 0.0) t_off = t;
  }
  ASSERT_GE(t_off, 0.0) << "the heater stayed on without the host";
  EXPECT_GE(t_off - t_stall, kConfirm - kReport - kStride);
  EXPECT_LE(t_off - t_stall, kConfirm + kReport);
  const auto board_state = mcu_link(rig).sim(0)->board().heater(0);
  EXPECT_TRUE(board_state.faulted);
  EXPECT_EQ(board_state.fault, protocol::HeaterFaultReason::kWatchdog);
  rig.loop->step_to(t_stall);  // (nothing: the host's time stood still)
  const auto f = rig.run_until(t_stall + 6.0 + 1.0);  // the host runs again, catching up from t_stall
  ASSERT_TRUE(f) << "the host did not learn of the MCU's fault";
  EXPECT_NE(f->find("heater extruder: mcu heater watchdog"), std::string::npos) << *f;
  std::printf("host stalled at %.2f s: the MCU turned the heater off after %.3f s\n", t_stall,
              t_off - t_stall);
}

// A MOSFET stuck on while the heater is off and the host is silent (no target: the 3 s rule does
// not apply): the MCU's own max-temp limit cuts it at the first sample past max_temp.
TEST(ThermalMcuLink, McusOwnMaxTempTripsWithTheHostSilent) {
  ThermalRig rig;
  ASSERT_FALSE(rig.run_until(2.0));
  sim::ThermalPlant& plant = rig.plant(0);
  const double max_c = rig.loop->spec(0).protection.max_temp_c;
  plant.inject(rig.t, sim::ThermalFaultKind::kHeaterStuckOn);
  const double t_silent = rig.t;
  double t_cross = -1, t_trip = -1;
  const auto& board = mcu_link(rig).sim(0)->board();
  double t = t_silent;
  for (; t < t_silent + 300.0 && t_trip < 0; t += 0.01) {
    mcu_link(rig).run_devices_only(t);
    if (t_cross < 0 && plant.sensor_temp_c() > max_c) t_cross = t;
    if (board.heater(0).faulted) t_trip = t;
  }
  ASSERT_GE(t_trip, 0.0) << "the MCU never tripped; sensor at " << plant.sensor_temp_c() << " C";
  EXPECT_EQ(board.heater(0).fault, protocol::HeaterFaultReason::kAdcRange);
  if (t_cross < 0) t_cross = t_trip;  // a noisy sample crossed before the true temperature did
  EXPECT_LE(t_trip - t_cross, kSample + 0.01);
  EXPECT_GT(plant.sensor_temp_c(), max_c - 2.0);
  const auto f = rig.run_until(t + 1.0);  // the host runs again, catching up from t_silent
  ASSERT_TRUE(f);
  EXPECT_NE(f->find("heater extruder: mcu max temperature"), std::string::npos) << *f;
  EXPECT_NE(f->find("(detected by the MCU)"), std::string::npos) << *f;
  std::printf("stuck MOSFET, host silent: %.1f s to max_temp, MCU trip %.3f s after: %s\n",
              t_cross - t_silent, t_trip - t_cross, f->c_str());
}

// A stopped heater MCU (here: an emergency stop sent to it) turns its heaters off at once (Klipper's
// MCU shutdown; it refuses SET_HEATER until identified again, fuzz_mcu_device checks the duty), and
// its session's failure is a thermal fault naming the MCU.
TEST(ThermalMcuLink, AStoppedHeaterMcuIsAThermalFaultWithItsHeatersOff) {
  ThermalRig rig;
  ASSERT_TRUE(rig.loop->set_target(0, 210.0).ok());
  ASSERT_FALSE(rig.run_until(10.0));
  ASSERT_GT(rig.plant(0).duty(), 0.5);
  mcu_link(rig).session(0).emergency_stop();
  const auto f = rig.run_until(rig.t + 1.0);
  ASSERT_TRUE(f);
  EXPECT_NE(f->find("heater MCU: MCU 'heaters' (mock heaters) reports emergency stop"), std::string::npos) << *f;
  EXPECT_LE(rig.t_fault - 10.0, 2 * kStride);
  EXPECT_EQ(rig.plant(0).duty(), 0.0);
  EXPECT_EQ(mcu_link(rig).sim(0)->board().heater(0).duty, 0);
  EXPECT_FALSE(rig.loop->set_target(0, 200.0).ok());
}

// A heater MCU that speaks protocol v2 knows no heater messages: refused with a message naming it.
TEST(ThermalMcuLink, AV2McuIsRefusedWithAMessage) {
  class Dev final : public SimulatedHeaterDevice {
   public:
    Dev() {
      device::VirtualMcuParams vp;
      vp.clock_hz = 1e6;
      vp.protocol_version = 2;
      std::snprintf(vp.name, sizeof vp.name, "old");
      device::MotorPort* none = nullptr;
      vmcu_ = std::make_unique<device::VirtualMcu>(vp, &none, 1, &board_);
    }
    const device::HeaterBoard& board() const override { return board_; }
    device::VirtualMcu& vmcu() override { return *vmcu_; }
    device::HeaterBoard board_{nullptr, 0, nullptr, 0, 1e6};
    std::unique_ptr<device::VirtualMcu> vmcu_;
  };
  HeaterMcu m;
  m.name = "old";
  auto dev = std::make_unique<Dev>();
  auto t = std::make_unique<drivers::MockTransport>(dev->vmcu(), drivers::MockFaults{}, "old");
  m.mock = t.get();
  m.transport = std::move(t);
  m.sim = std::move(dev);
  m.session.name = "old";
  m.session.encoder_period_s = 0.0;
  std::vector<HeaterMcu> mcus;
  mcus.push_back(std::move(m));
  ThermalOptions o = thermal_options(config::default_config());
  ThermalLoop loop(o, std::make_unique<McuHeaterLink>(std::move(mcus), std::vector<HeaterRoute>{{0, 0}, {0, 1}},
                                                      std::vector<HeaterRoute>{}, o.mcu_clock_hz));
  loop.start(0.0);
  std::optional<std::string> f;
  for (double t_s = 0.05; t_s < 2.0 && !f; t_s += 0.05) f = loop.step_to(t_s);
  ASSERT_TRUE(f);
  EXPECT_NE(f->find("heater MCU 'old' speaks protocol version 2: heaters and fans need version 3"),
            std::string::npos) << *f;
  EXPECT_FALSE(loop.set_target(0, 200.0).ok());
}

}  // namespace
}  // namespace feedloop::engine::testing
