// What the fuzz targets found on the MCU link (fuzz/corpus/mcu_host/regress_*,
// fuzz/corpus/mcu_device/regress_*): malformed messages that pass the CRC are refused whole, with
// a message, and never reach arithmetic that overflows or a motor that steps back in time; the
// device loop's parameters and telemetry stay in range whatever the numbers.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "drivers/device/axis_loop.hpp"
#include "drivers/device/saturate.hpp"
#include "drivers/device/stop_ramp.hpp"
#include "drivers/device/virtual_mcu.hpp"
#include "drivers/host/mcu_session.hpp"
#include "drivers/protocol/loop_messages.hpp"
#include "drivers/protocol/messages.hpp"
#include "drivers/protocol/reliable_link.hpp"
#include "drivers/stepgen/run_codec.hpp"

namespace feedloop::drivers {
namespace {

using protocol::MsgType;
using protocol::MsgWriter;

// A device played by the test: its messages go to the session over a real link.
class ScriptedDevice final : public Transport,
                             private protocol::FrameOutput,
                             private protocol::PayloadHandler {
 public:
  ScriptedDevice() { link_.configure({}, this, this); }
  Status open() override { return Status::Ok(); }
  void close() override {}
  bool connected() const override { return true; }
  Status write(const uint8_t* data, size_t n) override {
    link_.on_bytes(data, n, 0);
    return Status::Ok();
  }
  Result<size_t> read(uint8_t* buf, size_t cap) override {
    const size_t n = std::min(cap, rx_.size());
    std::memcpy(buf, rx_.data(), n);
    rx_.erase(rx_.begin(), rx_.begin() + static_cast<std::ptrdiff_t>(n));
    return n;
  }
  void poll(double, double) override {}
  std::string describe() const override { return "scripted"; }
  void send(const MsgWriter& w, const uint8_t* buf) { link_.send(buf, w.size(), 0); }

 private:
  void write_frame(const uint8_t* f, size_t n) override { rx_.insert(rx_.end(), f, f + n); }
  void on_payload(const uint8_t*, size_t) override {}
  protocol::ReliableLink link_;
  std::vector<uint8_t> rx_;
};

struct HostRig {
  ScriptedDevice dev;
  McuSession session{[] {
                       McuSessionParams p;
                       p.name = "x";
                       return p;
                     }(),
                     dev};
  double now = 0.0;
  HostRig() { EXPECT_TRUE(session.start(now).ok()); }
  void identify(uint64_t hz, uint8_t axis_byte) {
    uint8_t b[32];
    MsgWriter w(b, sizeof b);
    w.u8(static_cast<uint8_t>(MsgType::kIdentifyResponse))
        .u16(protocol::kProtocolVersion)
        .var(hz)
        .u8(axis_byte)
        .u8(0);
    dev.send(w, b);
    poll();
  }
  void poll() {
    now += 1e-3;
    session.poll(now);
  }
  bool has_event(const std::string& part) {
    for (const std::string& e : session.take_events())
      if (e.find(part) != std::string::npos) return true;
    return false;
  }
};

TEST(McuSessionInput, IdentifyWithAZeroClockFailsTheSessionNamingTheMcu) {
  HostRig rig;
  rig.identify(0, 0);  // fuzz/corpus/mcu_host/regress_identify_zero_hz
  EXPECT_EQ(rig.session.state(), McuState::kFailed);
  ASSERT_TRUE(rig.session.error().has_value());
  EXPECT_NE(rig.session.error()->message.find("MCU 'x'"), std::string::npos)
      << rig.session.error()->message;
  EXPECT_NE(rig.session.error()->message.find("clock of 0 Hz"), std::string::npos)
      << rig.session.error()->message;
}

TEST(McuSessionInput, IdentifyWithAClockAbove32BitsOrNineMotorsFails) {
  HostRig big;
  big.identify(uint64_t{1} << 32, 0);
  EXPECT_EQ(big.session.state(), McuState::kFailed);
  HostRig board;
  board.identify(20'000'000, 0x80 | 9);
  EXPECT_EQ(board.session.state(), McuState::kFailed);
  EXPECT_NE(board.session.error()->message.find("9 motors"), std::string::npos)
      << board.session.error()->message;
  HostRig ok;
  ok.identify(20'000'000, 0x80 | 4);
  EXPECT_TRUE(ok.session.ready());
  EXPECT_EQ(ok.session.mcu_axes(), 4);
  EXPECT_EQ(ok.session.mcu_clock_hz(), 20'000'000u);
}

TEST(McuSessionInput, EncoderReportWhoseClocksOverflowIsIgnoredWhole) {
  HostRig rig;
  rig.identify(20'000'000, 0);
  ASSERT_TRUE(rig.session.ready());
  uint8_t b[64];
  // fuzz/corpus/mcu_host/regress_encoder_clock_overflow: first + i * period beyond 2^63.
  MsgWriter bad(b, sizeof b);
  bad.u8(static_cast<uint8_t>(MsgType::kEncoderReport))
      .u8(0)
      .var(uint64_t{1} << 62)
      .var(uint64_t{1} << 62)
      .var(3);
  bad.zz(5).zz(1).zz(1);
  rig.dev.send(bad, b);
  rig.poll();
  std::vector<EncoderSample> samples;
  EXPECT_EQ(rig.session.take_encoder_samples(samples), 0u);
  EXPECT_TRUE(rig.has_event("malformed encoder report"));
  // Counts that overflow: also refused whole.
  MsgWriter counts(b, sizeof b);
  counts.u8(static_cast<uint8_t>(MsgType::kEncoderReport))
      .u8(0)
      .var(1000)
      .var(10)
      .var(2)
      .zz(INT64_MAX)
      .zz(1);
  rig.dev.send(counts, b);
  rig.poll();
  EXPECT_EQ(rig.session.take_encoder_samples(samples), 0u);
  // A good report after them arrives sample by sample.
  MsgWriter good(b, sizeof b);
  good.u8(static_cast<uint8_t>(MsgType::kEncoderReport))
      .u8(0)
      .var(1000)
      .var(10)
      .var(3)
      .zz(5)
      .zz(2)
      .zz(-4);
  rig.dev.send(good, b);
  rig.poll();
  ASSERT_EQ(rig.session.take_encoder_samples(samples), 3u);
  EXPECT_EQ(samples[2].clock, 1020);
  EXPECT_EQ(samples[2].counts, 3);
}

TEST(McuSessionInput, ClockResponseBeyond63BitsIsIgnored) {
  HostRig rig;
  rig.identify(20'000'000, 0);
  ASSERT_TRUE(rig.session.ready());
  rig.poll();  // the first clock query (token 1) goes out
  uint8_t b[32];
  // fuzz/corpus/mcu_host/regress_clock_response_overflow: the clock sync subtracted such clocks.
  MsgWriter w(b, sizeof b);
  w.u8(static_cast<uint8_t>(MsgType::kClockResponse)).var(1).var((uint64_t{1} << 63) + 5);
  rig.dev.send(w, b);
  rig.poll();
  EXPECT_EQ(rig.session.clock().samples(), 0);
  EXPECT_TRUE(rig.has_event("impossible clock"));
}

// ---- device side

struct StepLog final : device::MotorPort {
  std::vector<double> t;
  void step(double t_s, int) override { t.push_back(t_s); }
  void set_enabled(double, bool) override {}
  int64_t read_encoder_counts(double) override { return 0; }
};

// The host played by the test: numbered frames into the virtual MCU.
struct DeviceRig {
  StepLog motor;
  device::VirtualMcu mcu{[] {
                           device::VirtualMcuParams p;
                           p.clock_hz = 1e6;
                           return p;
                         }(),
                         &motor};
  uint16_t seq = 0;
  void send(const uint8_t* payload, size_t n) {
    uint8_t f[protocol::kMaxFrame];
    const uint8_t flags = static_cast<uint8_t>(protocol::kFlagData |
                                               (seq == 0 ? protocol::kFlagReset : 0) | (3 << 4));
    mcu.receive(f, protocol::encode_frame(f, flags, seq++, 0, payload, n), 0.0);
  }
  void identify() {
    const uint8_t id[3] = {static_cast<uint8_t>(MsgType::kIdentify),
                           protocol::kProtocolVersion & 0xFF, 0};
    send(id, sizeof id);
  }
  // QUEUE_STEPS for motor 0 starting at first_clock.
  void queue(uint64_t first_clock, const std::vector<stepgen::StepRun>& runs) {
    uint8_t b[protocol::kMaxPayload] = {static_cast<uint8_t>(MsgType::kQueueSteps), 0};
    stepgen::RunEncoder enc;
    ASSERT_TRUE(enc.begin(b + 2, sizeof b - 2, first_clock));
    for (const auto& r : runs) ASSERT_TRUE(enc.append(r));
    send(b, 2 + enc.size());
  }
};

TEST(VirtualMcuInput, ABatchWithARunThatStepsBackInTimeIsRefusedWhole) {
  DeviceRig rig;
  rig.identify();
  // fuzz/corpus/mcu_device/regress_negative_interval: intervals 11, -37, ... after a good run.
  rig.queue(10000, {{1000, -5, 10, 1}, {11, -48, 4, -1}});
  rig.mcu.run_until(1.0);
  EXPECT_EQ(rig.motor.t.size(), 0u);  // not even the good first run
  EXPECT_EQ(rig.mcu.status().last_error, protocol::McuError::kBadMessage);
  EXPECT_EQ(rig.mcu.status().queued_runs, 0u);
  // The next good batch runs: 10 steps, 1 ms apart from clock 1.01e6 (1.01 s at 1 MHz).
  rig.queue(1'010'000, {{1000, 0, 10, 1}});
  rig.mcu.run_until(2.0);
  ASSERT_EQ(rig.motor.t.size(), 10u);
  EXPECT_NEAR(rig.motor.t[0], 1.011, 1e-9);
  EXPECT_NEAR(rig.motor.t[9], 1.020, 1e-9);
}

TEST(VirtualMcuInput, ZeroIntervalsAndClocksBeyond63BitsAreMalformed) {
  DeviceRig rig;
  rig.identify();
  rig.queue(100, {{0, 0, 4'000'000'000u, 1}});  // would step 4e9 times at one clock
  rig.queue(uint64_t{1} << 63, {{10, 0, 1, 1}});
  rig.mcu.run_until(0.5);
  EXPECT_EQ(rig.motor.t.size(), 0u);
  EXPECT_EQ(rig.mcu.status().errors, 2u);
  EXPECT_EQ(rig.mcu.status().last_error, protocol::McuError::kBadMessage);
}

TEST(StepRunLaw, ValidRunsHavePositiveIntervalsAndRepresentableClocks) {
  using stepgen::run_is_valid;
  EXPECT_TRUE(run_is_valid(0, {1, 0, 1, 1}));
  EXPECT_FALSE(run_is_valid(0, {0, 0, 1, 1}));
  EXPECT_FALSE(run_is_valid(0, {5, 0, 0, 1}));
  EXPECT_TRUE(run_is_valid(0, {3, -1, 3, 1}));   // intervals 3, 2, 1
  EXPECT_FALSE(run_is_valid(0, {2, -1, 3, 1}));  // intervals 2, 1, 0
  EXPECT_TRUE(run_is_valid(0, {1, 0, 3'000'000'000u, 1}));
  EXPECT_FALSE(run_is_valid(0, {1, 0, 4'000'000'000u, 1}));  // n (n-1) overflows
  EXPECT_FALSE(run_is_valid(INT64_MAX - 10, {5, 0, 3, 1}));
  EXPECT_TRUE(run_is_valid(INT64_MAX - 15, {5, 0, 3, 1}));
  EXPECT_EQ(stepgen::run_end_clock(INT64_MAX - 15, {5, 0, 3, 1}), INT64_MAX);
}

TEST(RunCodecInput, IntervalsBeyond64BitsAreMalformed) {
  uint8_t b[64];
  size_t p = protocol::put_varint(b, 0, sizeof b, 0);
  for (int i = 0; i < 2; ++i) {  // two runs whose interval deltas sum beyond INT64_MAX
    p = protocol::put_varint(b, p, sizeof b, 2);
    p = protocol::put_varint(b, p, sizeof b, protocol::zigzag(INT64_MAX - 1));
    p = protocol::put_varint(b, p, sizeof b, 0);
  }
  stepgen::RunDecoder dec;
  ASSERT_TRUE(dec.begin(b, p));
  stepgen::StepRun r;
  ASSERT_TRUE(dec.next(r));
  EXPECT_EQ(r.interval_ticks, INT64_MAX - 1);
  EXPECT_FALSE(dec.next(r));
}

// ---- protocol v2 (the device loop)

// fuzz/corpus/mcu_device/regress_loop_rate_overflow: a valid but huge correction rate overflowed
// the float -> int32 cast of the steps allowed per tick. At most one step per MCU tick now.
TEST(AxisLoopInput, AHugeCorrectionRateIsCappedAtOneStepPerMcuTick) {
  device::AxisLoop loop;
  loop.init(1e6f);
  device::LoopParams p;
  p.enabled = true;
  p.period_ticks = 1000;
  p.nm_per_step_q16 = 10000u << 16;
  p.nm_per_count_q16 = 10000u << 16;
  p.max_correction_rate_nm_s = 1e30f;
  p.max_correction_nm = 1e12f;
  p.max_following_error_nm = 1e12f;
  ASSERT_EQ(loop.stage(p, 0), device::LoopParamError::kOk);
  ASSERT_TRUE(loop.push_target({0, 1'000'000'000}));  // 1 m away from the encoder's 0
  ASSERT_TRUE(loop.push_target({10'000'000, 1'000'000'000}));
  device::LoopTickOut out;
  for (int k = 0; k < 3; ++k) {
    device::LoopTickIn in;
    in.clock = loop.next_tick_clock();
    loop.tick(in, out);
  }
  EXPECT_EQ(loop.state(), device::LoopState::kRunning);
  EXPECT_EQ(out.extra_steps, 1000);  // the cap: the PI asks for ~5e4 steps
}

// fuzz/corpus/mcu_device/regress_stop_from_absurd_speed: knots 31 mm apart in 5 us, then a
// following-error trip (here: 12 m in 2 ms): the controlled stop braked from r's slope (6e12 nm/s)
// with no limit on the steps per tick, about 6e5 of them, and the virtual MCU took minutes for one
// period. The stop now starts from at most max_speed_nm_s and takes at most one step per MCU tick.
TEST(AxisLoopInput, AStopFromAnAbsurdTargetSlopeBrakesFromTheAxisMaximumSpeed) {
  device::AxisLoop loop;
  loop.init(1e6f);
  device::LoopParams p;
  p.enabled = true;
  p.period_ticks = 1000;
  p.nm_per_step_q16 = 10000u << 16;
  p.nm_per_count_q16 = 10000u << 16;
  p.max_speed_nm_s = 500e6f;  // 50 steps per 1 ms tick
  ASSERT_EQ(loop.stage(p, 0), device::LoopParamError::kOk);
  ASSERT_TRUE(loop.push_target({0, 0}));
  ASSERT_TRUE(loop.push_target({2000, 12'000'000'000}));  // 12 m in 2 ms: 6e12 nm/s
  ASSERT_TRUE(loop.push_target({10'000'000, 12'000'000'000}));
  int64_t motor_steps = 0;
  int32_t most = 0;
  int ticks = 0;
  device::LoopTickOut out;
  for (; ticks < 1000 && loop.state() != device::LoopState::kStopped; ++ticks) {
    device::LoopTickIn in;
    in.clock = loop.next_tick_clock();
    in.encoder_counts = motor_steps;  // the carriage follows the motor exactly
    in.motor_steps = motor_steps;
    in.device_steps = motor_steps;
    loop.tick(in, out);
    motor_steps += out.extra_steps;
    most = std::max(most, std::abs(out.extra_steps));
  }
  EXPECT_EQ(loop.stop_reason(), device::StopReason::kFollowingError);
  EXPECT_EQ(loop.state(), device::LoopState::kStopped);
  EXPECT_LE(most, 51);  // 500e6 nm/s x 1 ms / 10000 nm, +1 for rounding
  // Braking from 500 mm/s at 3000 mm/s^2 takes 167 ms: about 170 ticks, not 1.
  EXPECT_GT(ticks, 150);
  EXPECT_LT(ticks, 200);
}

// fuzz/corpus/mcu_device/regress_stop_ramp_inf: a valid but tiny stop deceleration made the
// ramp's duration infinite, and the float -> int64 casts of its end clock and positions undefined.
TEST(AxisLoopInput, AStopRampOfUnboundedLengthSaturates) {
  device::StopRamp ramp;
  ramp.start(1000, 5, 3e38f, 1e-30f, 1e6f);
  EXPECT_EQ(ramp.end_clock(), INT64_MAX);
  EXPECT_FALSE(ramp.done_at(INT64_MAX - 1));
  EXPECT_EQ(ramp.position_at(1000), 5);
  EXPECT_EQ(ramp.position_at(2000), INT64_MAX);  // 3e38 nm/s for 1 ms
  device::StopRamp back;
  back.start(0, -100, -3e38f, 1e-30f, 1e6f);
  EXPECT_EQ(back.position_at(1000), INT64_MIN);
  device::StopRamp normal;  // 500 mm/s at 3000 mm/s^2: 167 ms, 41.7 mm
  normal.start(0, 0, 500e6f, 3e9f, 1e6f);
  EXPECT_EQ(normal.end_clock(), 166'667);
  EXPECT_NEAR(static_cast<double>(normal.position_at(1'000'000)), 41'666'667.0, 10.0);
}

// fuzz/corpus/mcu_device/regress_slip_event_inf: an absurd target slope made the deflection model
// infinite and the slip event's size a float -> int64 cast of -inf. The device loop's conversions
// of wire-derived numbers go through drivers/device/saturate.hpp.
TEST(DeviceSaturation, ConversionsSaturateInsteadOfOverflowing) {
  using namespace device;
  EXPECT_EQ(saturate_i64(-INFINITY), INT64_MIN);
  EXPECT_EQ(saturate_i64(INFINITY), INT64_MAX);
  EXPECT_EQ(saturate_i64(std::nanf("")), 0);
  EXPECT_EQ(saturate_i64(-1234.9f), -1234);
  EXPECT_EQ(round_saturate_i64(-1234.5f), -1235);
  EXPECT_EQ(round_saturate_i32(3e9f), INT32_MAX);
  EXPECT_EQ(round_saturate_i32(-3e9f), INT32_MIN);
  EXPECT_EQ(round_saturate_i32(2.5f), 3);
  EXPECT_EQ(add_saturate_i64(INT64_MAX - 1, 5), INT64_MAX);
  EXPECT_EQ(sub_saturate_i64(INT64_MIN + 1, 5), INT64_MIN);
  EXPECT_EQ(sub_saturate_i64(5, INT64_MIN), INT64_MAX);
  EXPECT_EQ(mul_saturate_i64(int64_t{1} << 40, -(int64_t{1} << 40)), INT64_MIN);
  EXPECT_EQ(mul_saturate_i64(-(int64_t{1} << 40), -(int64_t{1} << 40)), INT64_MAX);
  EXPECT_EQ(mul_saturate_i64(-3, 7), -21);
}

// fuzz/corpus/mcu_device/regress_target_overflow: QUEUE_TARGET's deltas summed beyond int64.
TEST(LoopProtocolInput, TargetKnotsBeyondInt64AreMalformed) {
  uint8_t b[64] = {static_cast<uint8_t>(MsgType::kQueueTarget), 0};
  size_t n = protocol::put_varint(b, 2, sizeof b, 3);                         // 3 knots
  n = protocol::put_varint(b, n, sizeof b, 100);                              // clock 100
  n = protocol::put_varint(b, n, sizeof b, protocol::zigzag(INT64_MAX - 5));  // position
  n = protocol::put_varint(b, n, sizeof b, 10);                               // +10 ticks
  n = protocol::put_varint(b, n, sizeof b, protocol::zigzag(3));              // +3 nm: fits
  n = protocol::put_varint(b, n, sizeof b, 10);
  n = protocol::put_varint(b, n, sizeof b, protocol::zigzag(3));  // +3 nm: beyond
  protocol::QueueTargetReader r;
  ASSERT_TRUE(r.begin(b, n));
  device::TargetKnot k;
  ASSERT_TRUE(r.next(k));
  ASSERT_TRUE(r.next(k));
  EXPECT_EQ(k.pos_nm, INT64_MAX - 2);
  EXPECT_EQ(k.clock, 110);
  EXPECT_FALSE(r.next(k));
  EXPECT_FALSE(r.ok());
}

// fuzz/corpus/mcu_host/regress_loop_report_nan: LOOP_REPORT's float error and correction went to
// the wire through a float -> int64 cast, undefined for NaN and beyond 2^63. Saturated now.
TEST(LoopProtocolInput, NonFiniteAndHugeTelemetryIsSaturatedOnTheWire) {
  protocol::LoopReportMsg m;
  m.report.e_nm = std::nanf("");
  m.report.u_nm = -1e30f;
  uint8_t buf[protocol::kMaxPayload];
  const size_t n = protocol::encode_loop_report(m, buf, sizeof buf);
  ASSERT_GT(n, 0u);
  protocol::LoopReportMsg d;
  ASSERT_TRUE(protocol::decode_loop_report(buf, n, d));
  EXPECT_EQ(d.report.e_nm, 0.0f);
  EXPECT_EQ(d.report.u_nm, static_cast<float>(INT64_MIN));
}


// The correction's step quantisation (axis_loop.cpp step 5): with kp 1 and the encoder hovering
// 0.4-0.6 steps from r (a carriage ringing around a half step), plain rounding toggles a step
// out and back; with a reversal hysteresis of half a step the step goes out once and stays.
// (The delta's carriages need the hysteresis: the toggling fed their 46-65 Hz mode.)
TEST(AxisLoopInput, AReversalHysteresisStopsAStepTogglingAtHalfAStep) {
  for (const float hysteresis : {0.0f, 0.5f}) {
    SCOPED_TRACE(hysteresis);
    device::AxisLoop loop;
    loop.init(1e6f);
    device::LoopParams p;
    p.enabled = true;
    p.period_ticks = 1000;
    p.nm_per_step_q16 = 10000u << 16;  // 10 um steps
    p.nm_per_count_q16 = 100u << 16;   // 0.1 um counts
    p.kp = 1.0f;
    p.ki_per_s = 0.0f;
    p.reversal_hysteresis_steps = hysteresis;
    ASSERT_EQ(loop.stage(p, 0), device::LoopParamError::kOk);
    ASSERT_TRUE(loop.push_target({0, 0}));
    ASSERT_TRUE(loop.push_target({1'000'000'000, 0}));  // r = 0 for 1000 s
    int64_t device_steps = 0, reversals = 0, steps_out = 0;
    int last_dir = 0;
    for (int k = 0; k < 200; ++k) {
      device::LoopTickIn in;
      in.clock = loop.next_tick_clock();
      // The carriage 4-6 um below r, alternating: e = r - y = +4..+6 um, u = e (kp 1).
      in.encoder_counts = k % 2 == 0 ? -60 : -40;
      in.motor_steps = device_steps;
      in.device_steps = device_steps;
      device::LoopTickOut out;
      loop.tick(in, out);
      device_steps += out.extra_steps;  // the owner executes them before the next tick
      if (out.extra_steps != 0) {
        ++steps_out;
        const int dir = out.extra_steps > 0 ? 1 : -1;
        if (last_dir != 0 && dir != last_dir) ++reversals;
        last_dir = dir;
      }
    }
    EXPECT_EQ(loop.state(), device::LoopState::kRunning);
    if (hysteresis == 0.0f) {
      EXPECT_GT(reversals, 50);  // out at 6 um, back at 4 um: every other tick
    } else {
      EXPECT_EQ(steps_out, 1);   // out at 6 um; back only below 0 um, which never comes
      EXPECT_EQ(reversals, 0);
      EXPECT_EQ(device_steps, 1);
    }
  }
}

TEST(AxisLoopInput, ReversalHysteresisOutsideZeroToFourStepsIsRejected) {
  device::LoopParams p;
  p.enabled = true;
  p.period_ticks = 1000;
  p.nm_per_step_q16 = 10000u << 16;
  p.nm_per_count_q16 = 100u << 16;
  p.reversal_hysteresis_steps = -0.1f;
  EXPECT_EQ(device::validate_loop_params(p), device::LoopParamError::kHysteresis);
  p.reversal_hysteresis_steps = 4.5f;
  EXPECT_EQ(device::validate_loop_params(p), device::LoopParamError::kHysteresis);
  p.reversal_hysteresis_steps = NAN;
  EXPECT_EQ(device::validate_loop_params(p), device::LoopParamError::kHysteresis);
  p.reversal_hysteresis_steps = 0.5f;
  EXPECT_EQ(device::validate_loop_params(p), device::LoopParamError::kOk);
}

}  // namespace
}  // namespace feedloop::drivers
