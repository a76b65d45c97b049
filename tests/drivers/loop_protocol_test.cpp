// Protocol v2 loop messages: round trips, malformed input refused, and the target compressor's
// error bound on a printing-like r(t).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "drivers/protocol/loop_messages.hpp"
#include "drivers/protocol/target_codec.hpp"

using namespace feedloop;

TEST(LoopProtocol, ConfigureLoopRoundTripsAndRefusesTruncation) {
  protocol::ConfigureLoopMsg m;
  m.axis = 2;
  m.activation_clock = 123456789012;
  m.params.enabled = true;
  m.params.period_ticks = 2000;
  m.params.nm_per_count_q16 = 490u << 16;
  m.params.nm_per_step_q16 = 10603u << 16;
  m.params.kp = 0.75f;
  m.params.ki_per_s = 33.5f;
  m.params.slip_cycle_nm = 678000.0f;
  m.params.deflection_s = 0.0069f;
  m.params.deflection_from_host_steps = true;
  m.params.sub_step_trim = true;
  m.params.horizon_margin_ticks = 400000;
  m.params.reversal_hysteresis_steps = 0.5f;
  uint8_t buf[protocol::kMaxPayload];
  const size_t n = protocol::encode_configure_loop(m, buf, sizeof buf);
  ASSERT_GT(n, 0u);
  EXPECT_LT(n, 100u);
  protocol::ConfigureLoopMsg d;
  ASSERT_TRUE(protocol::decode_configure_loop(buf, n, d));
  EXPECT_EQ(d.axis, 2);
  EXPECT_EQ(d.activation_clock, 123456789012);
  EXPECT_TRUE(d.params.enabled);
  EXPECT_EQ(d.params.period_ticks, 2000u);
  EXPECT_EQ(d.params.nm_per_step_q16, 10603u << 16);
  EXPECT_EQ(d.params.kp, 0.75f);
  EXPECT_EQ(d.params.ki_per_s, 33.5f);
  EXPECT_EQ(d.params.slip_cycle_nm, 678000.0f);
  EXPECT_EQ(d.params.deflection_s, 0.0069f);
  EXPECT_TRUE(d.params.deflection_from_host_steps);  // flags bit 2
  EXPECT_TRUE(d.params.sub_step_trim);               // flags bit 4
  EXPECT_EQ(d.params.horizon_margin_ticks, 400000u);
  EXPECT_EQ(d.params.report_every_ticks, m.params.report_every_ticks);
  EXPECT_EQ(d.params.reversal_hysteresis_steps, 0.5f);
  // The trailing hysteresis is optional: a message from before it decodes with plain rounding.
  ASSERT_TRUE(protocol::decode_configure_loop(buf, n - 4, d));
  EXPECT_EQ(d.params.reversal_hysteresis_steps, 0.0f);
  EXPECT_EQ(d.params.report_every_ticks, m.params.report_every_ticks);
  EXPECT_FALSE(protocol::decode_configure_loop(buf, n - 1, d));
  EXPECT_EQ(protocol::encode_configure_loop(m, buf, 20), 0u);  // does not fit: 0, not a partial message
}

TEST(LoopProtocol, ReportAndEventRoundTrip) {
  protocol::LoopReportMsg r;
  r.axis = 1;
  r.report.clock = 99999999;
  r.report.state = device::LoopState::kStopping;
  r.report.r_nm = 150000000;
  r.report.y_nm = 149999000;
  r.report.e_nm = 1000.0f;
  r.report.u_nm = -25000.0f;
  r.report.device_steps = -3;
  r.report.max_tick_cost = 87;
  r.report.ticks = 5000;
  r.report.deadline_misses = 2;
  uint8_t buf[96];
  const size_t n = protocol::encode_loop_report(r, buf, sizeof buf);
  ASSERT_GT(n, 0u);
  protocol::LoopReportMsg d;
  ASSERT_TRUE(protocol::decode_loop_report(buf, n, d));
  EXPECT_EQ(d.report.state, device::LoopState::kStopping);
  EXPECT_EQ(d.report.y_nm, 149999000);
  EXPECT_EQ(d.report.e_nm, 1000.0f);
  EXPECT_EQ(d.report.u_nm, -25000.0f);
  EXPECT_EQ(d.report.device_steps, -3);
  EXPECT_EQ(d.report.max_tick_cost, 87u);
  EXPECT_EQ(d.report.deadline_misses, 2u);

  protocol::LoopEventMsg e{3, {device::LoopEventKind::kSlip, 4242, -1, -678000}};
  const size_t m = protocol::encode_loop_event(e, buf, sizeof buf);
  protocol::LoopEventMsg f;
  ASSERT_TRUE(protocol::decode_loop_event(buf, m, f));
  EXPECT_EQ(f.axis, 3);
  EXPECT_EQ(f.event.kind, device::LoopEventKind::kSlip);
  EXPECT_EQ(f.event.clock, 4242);
  EXPECT_EQ(f.event.b, -678000);
  buf[2] = 77;  // unknown kind
  EXPECT_FALSE(protocol::decode_loop_event(buf, m, f));
}

TEST(LoopProtocol, CompressedTargetStaysWithinItsBound) {
  // r(t) of a circle's x at 100 mm/s, r = 10 mm (a = 1000 mm/s^2), sampled every 0.5 ms for 2 s,
  // compressed at 0.5 um; the knots decoded from QUEUE_TARGET messages must reproduce every
  // sample within 0.5 um.
  const double hz = 20e6, eps_nm = 500.0;
  protocol::TargetCompressor c;
  c.configure(eps_nm, static_cast<int64_t>(0.02 * hz));
  std::vector<device::TargetKnot> knots;
  std::vector<std::pair<int64_t, double>> samples;
  device::TargetKnot k;
  for (int i = 0; i <= 4000; ++i) {
    const double t = i * 0.0005;
    const int64_t clock = static_cast<int64_t>(std::llround(t * hz));
    const double x_nm = 1e6 * (50.0 + 10.0 * std::cos(10.0 * t));
    samples.push_back({clock, x_nm});
    if (c.push(clock, x_nm, k)) knots.push_back(k);
  }
  if (c.flush(k)) knots.push_back(k);
  // Through the wire, in messages of up to 30 knots.
  std::vector<device::TargetKnot> wire;
  size_t bytes = 0;
  for (size_t i = 0; i < knots.size(); i += 30) {
    const int cnt = static_cast<int>(std::min<size_t>(30, knots.size() - i));
    uint8_t buf[protocol::kMaxPayload];
    const size_t n = protocol::encode_queue_target(0, &knots[i], cnt, buf, sizeof buf);
    ASSERT_GT(n, 0u);
    bytes += n;
    protocol::QueueTargetReader r;
    ASSERT_TRUE(r.begin(buf, n));
    while (r.next(k)) wire.push_back(k);
    ASSERT_TRUE(r.ok());
  }
  ASSERT_EQ(wire.size(), knots.size());
  double max_err = 0;
  size_t j = 0;
  for (const auto& [clock, x] : samples) {
    while (j + 1 < wire.size() && wire[j + 1].clock <= clock) ++j;
    double r = static_cast<double>(wire[j].pos_nm);
    if (j + 1 < wire.size() && clock > wire[j].clock)
      r += static_cast<double>(wire[j + 1].pos_nm - wire[j].pos_nm) * static_cast<double>(clock - wire[j].clock) /
           static_cast<double>(wire[j + 1].clock - wire[j].clock);
    max_err = std::max(max_err, std::abs(r - x));
  }
  std::printf("%zu samples -> %zu knots (%.1f ms apart), %zu bytes (%.0f B/s), max error %.1f nm\n", samples.size(),
              knots.size(), 2000.0 / static_cast<double>(knots.size()), bytes, static_cast<double>(bytes) / 2.0, max_err);
  EXPECT_LE(max_err, eps_nm);
  EXPECT_LT(knots.size(), samples.size() / 4);  // it compresses
  // Malformed: a zero clock step is refused.
  uint8_t bad[] = {static_cast<uint8_t>(protocol::MsgType::kQueueTarget), 0, 2, 10, 0, 0, 5};
  protocol::QueueTargetReader r;
  ASSERT_TRUE(r.begin(bad, sizeof bad));
  EXPECT_TRUE(r.next(k));
  EXPECT_FALSE(r.next(k));
  EXPECT_FALSE(r.ok());
}
