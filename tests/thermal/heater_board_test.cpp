// The device side of heaters (protocol v3): messages round-trip; the board samples and reports,
// applies the duty, and turns the heater off on its own on a missing confirmation (3 s) and on
// its own ADC limit, with a HEATER_FAULT.
#include <gtest/gtest.h>

#include "drivers/device/heater_board.hpp"
#include "drivers/protocol/heater_messages.hpp"
#include "sim/thermal_plant.hpp"
#include "thermal/sensor.hpp"

namespace feedloop {
namespace {

using protocol::HeaterFaultReason;

TEST(HeaterMessages, RoundTripAndRejectTruncation) {
  uint8_t buf[32];
  protocol::ConfigureHeaterMsg c{1, 30000, 8, 100, 65000, 3000000, 60000};
  const size_t n = protocol::encode_configure_heater(c, buf, sizeof buf);
  ASSERT_GT(n, 0u);
  EXPECT_EQ(buf[0], 0x0B);
  protocol::ConfigureHeaterMsg d;
  ASSERT_TRUE(protocol::decode_configure_heater(buf, n, d));
  EXPECT_EQ(d.sample_period_ticks, 30000u);
  EXPECT_EQ(d.adc_max, 65000);
  EXPECT_EQ(d.confirm_timeout_ticks, 3000000u);
  EXPECT_FALSE(protocol::decode_configure_heater(buf, n - 1, d));
  protocol::HeaterReportMsg r{2, 123456789, 4321, 777};
  const size_t m = protocol::encode_heater_report(r, buf, sizeof buf);
  EXPECT_EQ(buf[0], 0x8C);
  protocol::HeaterReportMsg r2;
  ASSERT_TRUE(protocol::decode_heater_report(buf, m, r2));
  EXPECT_EQ(r2.clock, 123456789);
  EXPECT_EQ(r2.adc, 4321);
  protocol::SetHeaterMsg sh;
  EXPECT_FALSE(protocol::decode_set_heater(buf, m, sh));
}

struct Rig {
  sim::ThermalPlant plant{sim::ThermalPlantParams{}};
  device::HeaterPort* port = &plant;
  device::HeaterBoard board{&port, 1, nullptr, 0, 1e6};
  uint8_t buf[32];
  void send(size_t n, int64_t clock) { ASSERT_TRUE(board.on_message(buf, n, clock)); }
  void configure(uint16_t adc_min, int64_t clock) {
    send(protocol::encode_configure_heater({0, 37500, 8, adc_min, 65000, 3000000, 65535}, buf,
                                           sizeof buf),
         clock);
  }
  void set(uint16_t duty, int64_t clock) {
    send(protocol::encode_set_heater({0, duty}, buf, sizeof buf), clock);
  }
};

TEST(HeaterBoard, ReportsEvery300msAndTurnsTheHeaterOff3sAfterTheLastConfirmation) {
  Rig r;
  r.configure(100, 0);
  r.set(65535, 0);
  int reports = 0;
  protocol::HeaterFaultMsg fault;
  bool faulted = false;
  for (int64_t c = 0; c <= 5000000 && !faulted; c += 10000) {
    r.board.run(c);
    uint8_t m[32];
    size_t n;
    while (r.board.pop_message(m, n)) {
      if (m[0] == 0x8C) ++reports;
      if (m[0] == 0x8D) faulted = protocol::decode_heater_fault(m, n, fault);
    }
  }
  ASSERT_TRUE(faulted);
  EXPECT_EQ(fault.reason, HeaterFaultReason::kWatchdog);
  EXPECT_NEAR(static_cast<double>(fault.clock), 3.0e6, 37500.0);  // within one sample of 3 s
  EXPECT_EQ(reports, 10);                                         // 3.0 s / 0.3 s
  EXPECT_EQ(r.plant.duty(), 0.0);
  EXPECT_GT(r.plant.block_temp_c(), 26.0);  // it did heat (1 s delay, then 3.3 C/s)
  r.set(65535, 5100000);                    // latched: stays off until reconfigured
  EXPECT_EQ(r.plant.duty(), 0.0);
}

TEST(HeaterBoard, ConfirmedHeaterStaysOnAndItsOwnLimitCutsAStuckHost) {
  Rig r;
  // adc_min: the adc at 250 C (hotter is lower): the MCU's own max temperature.
  const auto s = *thermal::builtin_sensor("Semitec 104GT-2");
  r.configure(static_cast<uint16_t>(thermal::adc_at(s, 250.0) * 65535.0), 0);
  protocol::HeaterFaultMsg fault;
  bool faulted = false;
  for (int64_t c = 0; c <= 400000000 && !faulted; c += 100000) {
    if (c % 1000000 == 0) r.set(65535, c);  // a host that confirms full power every second
    r.board.run(c);
    uint8_t m[32];
    size_t n;
    while (r.board.pop_message(m, n))
      if (m[0] == 0x8D) faulted = protocol::decode_heater_fault(m, n, fault);
  }
  ASSERT_TRUE(faulted);
  EXPECT_EQ(fault.reason, HeaterFaultReason::kAdcRange);
  EXPECT_EQ(r.plant.duty(), 0.0);
  EXPECT_NEAR(r.plant.sensor_temp_c(), 250.0, 3.0);
}

}  // namespace
}  // namespace feedloop
