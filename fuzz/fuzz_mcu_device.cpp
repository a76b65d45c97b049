// libFuzzer target for the device side of the MCU link: device::VirtualMcu receiving whatever a
// host sends. The input plays the host; the harness's host has a real protocol::ReliableLink, so
// well-formed messages arrive in order and the device's frames are acknowledged. The MCU runs
// at 1 MHz with 1 to 4 motors (first input byte), and at most 0.2 s of virtual time passes, which
// bounds the steps any input can ask for (one per tick at most).
// Operations (fuzz_input.hpp):
//   0 N bytes[N]       the host sends a message (payload = bytes) over its link
//   1 N bytes[N]       raw bytes on the wire
//   2 F S S A A N b[N] a frame with flags F, seq, ack (little endian) and a correct CRC
//   3 T                T * 0.1 ms pass (run_until)
//   4 A D D R (C I I D)*R  QUEUE_STEPS for motor A: first clock = now + D ticks, R runs of
//                      count C+1, interval I (u16) and add D (int8), encoded with RunEncoder
//   5 V V P P R W W    IDENTIFY with version V, then CONFIGURE(encoder period P ticks,
//                      R samples per report, watchdog W * 100 ticks)
//   6 E                ENABLE E&1
//   7                  the host's link polls (retransmits) and asks for STATUS
//   8 A D D K (F V V V V)*K  protocol v2 CONFIGURE_LOOP for motor A, active from now + D ticks:
//                      a working parameter set (1 kHz, the encoder of the fake motor) with K
//                      fields F changed to the 32 bits V (floats as their bits: NaN, inf...)
//   9 A D D K (C C P P)*K  protocol v2 QUEUE_TARGET for motor A: K knots, the first at now + D
//                      ticks, then clock steps C and position steps P * 1000 nm (int16)
//  10 A L T T C        protocol v3 ENDSTOP_HOME for motor A: trigger level L, sample period T
//                      ticks (0 disarms), C samples (each motor's switch closes at 50 steps)
//  11 A                protocol v3 ENDSTOP_QUERY for motor A
// (op bytes 240..255 select 12..14; every other byte b selects b % 12, as before they existed)
//  12 H P P P R L L U U W W W M M  protocol v3 CONFIGURE_HEATER for heater H: sample period P
//                      ticks (u24), R samples per report, ADC range [L, U], confirm timeout W
//                      ticks (u24), max duty M (the board has 2 heaters, 2 fans)
//  13 H D D            protocol v3 SET_HEATER heater H, duty D
//  14 F D D            protocol v3 SET_FAN fan F, duty D
// Invariants (trap): every frame the device sends is whole with a valid CRC and carries a
// device-to-host message type (v1, v2 or v3); each motor's steps and enable changes never go back
// in time (MotorPort's contract) and have direction +-1; no queue holds more runs than kMaxRuns;
// heater and fan duties stay in [0, 1] with their times never going back; a heater is off (duty 0)
// while the MCU is stopped and while its board latched a fault.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>

#include "drivers/device/heater_board.hpp"
#include "drivers/device/virtual_mcu.hpp"
#include "drivers/protocol/heater_messages.hpp"
#include "drivers/protocol/endstop_messages.hpp"
#include "drivers/protocol/loop_messages.hpp"
#include "drivers/protocol/messages.hpp"
#include "drivers/protocol/reliable_link.hpp"
#include "drivers/stepgen/run_codec.hpp"
#include "fuzz/fuzz_input.hpp"

namespace {

using namespace feedloop;
using fuzz::check;
using fuzz::FuzzInput;
using protocol::MsgType;

constexpr double kClockHz = 1e6;
constexpr double kMaxTimeS = 0.2;

class Motor final : public device::MotorPort {
 public:
  void step(double t_s, int direction) override {
    check(direction == 1 || direction == -1);
    advance(t_s);
    position += direction;
  }
  void set_enabled(double t_s, bool) override { advance(t_s); }
  int64_t read_encoder_counts(double t_s) override {
    advance(t_s);
    return position * 3;
  }
  bool read_endstop(double t_s) override {  // a switch that closes past endstop_steps
    advance(t_s);
    return position >= endstop_steps;
  }
  int64_t position = 0;
  int64_t endstop_steps = 50;

 private:
  void advance(double t_s) {
    check(std::isfinite(t_s));
    check(t_s >= last_s_);  // never back in time
    last_s_ = t_s;
  }
  double last_s_ = -1e300;
};

// A heater PWM and its ADC: duty within [0, 1], times never back; the ADC sweeps the full scale
// (so the MCU's range limit trips on some configurations and not on others).
class Heater final : public device::HeaterPort, public device::FanPort {
 public:
  void set_duty(double t_s, double d) override {
    advance(t_s);
    check(d >= 0.0 && d <= 1.0);
    duty = d;
  }
  uint16_t read_adc(double t_s) override {
    advance(t_s);
    return static_cast<uint16_t>(static_cast<int64_t>(t_s * 2e5) & 0xFFFF);
  }
  double duty = 0.0;

 private:
  void advance(double t_s) {
    check(std::isfinite(t_s));
    check(t_s >= last_s_);
    last_s_ = t_s;
  }
  double last_s_ = -1e300;
};

// The host end: its link's frames go into the device, the device's frames into its link.
class FakeHost final : private protocol::FrameOutput, private protocol::PayloadHandler {
 public:
  explicit FakeHost(device::VirtualMcu& mcu) : mcu_(mcu) {
    protocol::LinkParams lp;
    lp.initial_epoch = 9;
    link_.configure(lp, this, this);
    link_.reset();
  }
  void send(const uint8_t* p, size_t n) {
    link_.send(p, n, ns());
    drain();
  }
  void put(const uint8_t* p, size_t n) {
    mcu_.receive(p, n, now_s);
    drain();
  }
  void poll() {
    link_.poll(ns());
    drain();
  }
  // Passes the device's frames to the host link (whose acks go back to the device).
  void drain() {
    uint8_t frame[protocol::kMaxFrame];
    size_t n = 0;
    for (int guard = 0; guard < 1000 && mcu_.pop_frame(frame, n); ++guard) {
      check(n >= protocol::kFrameOverhead && n <= protocol::kMaxFrame);
      n = n < sizeof frame ? n : sizeof frame;  // the check traps first; this bound is for GCC's
                                                // -Warray-bounds, which cannot see that it does
      protocol::FrameDecoder dec;
      check(dec.feed(frame, n) == n);
      protocol::FrameView f;
      check(dec.next(f));
      check(f.len + protocol::kFrameOverhead == n);
      link_.on_bytes(frame, n, ns());
    }
  }
  double now_s = 0.0;

 private:
  int64_t ns() const { return static_cast<int64_t>(now_s * 1e9); }
  void write_frame(const uint8_t* frame, size_t n) override { mcu_.receive(frame, n, now_s); }
  void on_payload(const uint8_t* p, size_t n) override {
    check(n >= 1);
    const auto t = static_cast<MsgType>(p[0]);
    check(protocol::is_device_to_host(t));
  }

  device::VirtualMcu& mcu_;
  protocol::ReliableLink link_;
};

// A loop parameter set that works with Motor (3 encoder counts per step) at kClockHz, with
// fields changed by the input.
device::LoopParams loop_params(FuzzInput& in) {
  device::LoopParams p;
  p.enabled = true;
  p.period_ticks = static_cast<uint32_t>(kClockHz / 1000);
  p.nm_per_step_q16 = 10602u << 16;
  p.nm_per_count_q16 = 3534u << 16;
  for (int k = in.u8() % 4; k > 0; --k) {
    const uint8_t field = in.u8() % 21;
    const uint32_t v = in.u32();
    float f = 0.0f;
    std::memcpy(&f, &v, sizeof f);
    switch (field) {
      case 0:
        p.enabled = v & 1;
        break;
      case 1:
        p.period_ticks = v;
        break;
      case 2:
        p.nm_per_count_q16 = v;
        break;
      case 3:
        p.nm_per_step_q16 = v;
        break;
      case 4:
        p.kp = f;
        break;
      case 5:
        p.ki_per_s = f;
        break;
      case 6:
        p.max_correction_nm = f;
        break;
      case 7:
        p.max_correction_rate_nm_s = f;
        break;
      case 8:
        p.max_following_error_nm = f;
        break;
      case 9:
        p.max_speed_nm_s = f;
        break;
      case 10:
        p.encoder_margin_nm = f;
        break;
      case 11:
        p.encoder_reject_limit = v;
        break;
      case 12:
        p.slip_threshold_nm = f;
        break;
      case 13:
        p.slip_cycle_nm = f;
        break;
      case 14:
        p.slip_settle_s = f;
        break;
      case 15:
        p.deflection_s2 = f;
        break;
      case 16:
        p.deflection_s = f;
        break;
      case 17:
        p.accel_filter_s = f;
        break;
      case 18:
        p.stop_decel_nm_s2 = f;
        break;
      case 19:
        p.horizon_margin_ticks = v;
        break;
      default:
        p.report_every_ticks = v;
        break;
    }
  }
  return p;
}

void send_msg(FakeHost& host, protocol::MsgWriter& w, const uint8_t* buf) {
  if (w.ok()) host.send(buf, w.size());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  FuzzInput in(data, size);
  const int motors = 1 + in.u8() % device::VirtualMcu::kMaxAxes;
  Motor ports[device::VirtualMcu::kMaxAxes];
  device::MotorPort* port_ptrs[device::VirtualMcu::kMaxAxes] = {&ports[0], &ports[1], &ports[2],
                                                                &ports[3]};
  device::VirtualMcuParams params;
  params.clock_hz = kClockHz;
  std::strcpy(params.name, "fuzz-mcu");
  Heater heaters[2], fans[2];
  device::HeaterPort* heater_ptrs[2] = {&heaters[0], &heaters[1]};
  device::FanPort* fan_ptrs[2] = {&fans[0], &fans[1]};
  device::HeaterBoard board(heater_ptrs, 2, fan_ptrs, 2, kClockHz);
  auto mcu = std::make_unique<device::VirtualMcu>(params, port_ptrs, motors, &board);  // 0.5 MB of queues
  FakeHost host(*mcu);
  uint8_t buf[protocol::kMaxPayload];
  while (!in.empty()) {
    size_t n = 0;
    const uint8_t op_byte = in.u8();
    const uint8_t op = op_byte >= 240 ? static_cast<uint8_t>(12 + (op_byte - 240) % 3) : op_byte % 12;
    if (op == 0) {
      const uint8_t* p = in.take(in.u8(), n);
      host.send(p, n);
    } else if (op == 1) {
      const uint8_t* p = in.take(in.u8(), n);
      host.put(p, n);
    } else if (op == 2) {
      const uint8_t flags = in.u8();
      const uint16_t seq = in.u16(), ack = in.u16();
      const uint8_t* p = in.take(in.u8() % (protocol::kMaxPayload + 1), n);
      uint8_t frame[protocol::kMaxFrame];
      host.put(frame, protocol::encode_frame(frame, flags, seq, ack, p, n));
    } else if (op == 3) {
      host.now_s = std::min(kMaxTimeS, host.now_s + 1e-4 * in.u8());
      mcu->run_until(host.now_s);
      host.drain();
    } else if (op == 4) {
      protocol::MsgWriter w(buf, sizeof buf);
      w.u8(static_cast<uint8_t>(MsgType::kQueueSteps)).u8(in.u8());
      const uint64_t first = static_cast<uint64_t>(mcu->clock_at(host.now_s) + in.u16());
      stepgen::RunEncoder enc;
      enc.begin(buf + w.size(), sizeof buf - w.size(), first);
      for (int r = in.u8() % 32; r > 0; --r) {
        stepgen::StepRun run;
        run.count = 1u + in.u8();
        run.interval_ticks = in.u16();
        run.add_ticks = static_cast<int8_t>(in.u8());
        run.direction = (run.count & 1) ? 1 : -1;
        if (!enc.append(run)) break;
      }
      host.send(buf, w.size() + enc.size());
    } else if (op == 5) {
      protocol::MsgWriter id(buf, sizeof buf);
      id.u8(static_cast<uint8_t>(MsgType::kIdentify)).u16(in.u16());
      send_msg(host, id, buf);
      protocol::MsgWriter cfg(buf, sizeof buf);
      cfg.u8(static_cast<uint8_t>(MsgType::kConfigure))
          .var(in.u16())
          .var(in.u8())
          .var(uint64_t{100} * in.u16());
      send_msg(host, cfg, buf);
    } else if (op == 6) {
      protocol::MsgWriter w(buf, sizeof buf);
      w.u8(static_cast<uint8_t>(MsgType::kEnable)).u8(in.u8() & 1);
      send_msg(host, w, buf);
    } else if (op == 7) {
      host.poll();
      buf[0] = static_cast<uint8_t>(MsgType::kStatusQuery);
      host.send(buf, 1);
    } else if (op == 8) {
      protocol::ConfigureLoopMsg m;
      m.axis = in.u8();
      m.activation_clock = mcu->clock_at(host.now_s) + in.u16();
      m.params = loop_params(in);
      if (const size_t len = protocol::encode_configure_loop(m, buf, sizeof buf))
        host.send(buf, len);
    } else if (op == 10) {
      protocol::EndstopHomeMsg m;
      m.axis = in.u8();
      m.trigger_level = in.u8();
      m.sample_ticks = in.u16();
      m.sample_count = in.u8();
      // The trigger source from the level byte's high bit (no extra input byte: the corpus keeps
      // its meaning): kNow, the host's relayed trigger.
      if (m.trigger_level & 0x80) m.source = protocol::EndstopSource::kNow;
      if (const size_t len = protocol::encode_endstop_home(m, buf, sizeof buf)) host.send(buf, len);
    } else if (op == 11) {
      protocol::EndstopQueryMsg m;
      m.axis = in.u8();
      if (const size_t len = protocol::encode_endstop_query(m, buf, sizeof buf)) host.send(buf, len);
    } else if (op == 12) {
      protocol::ConfigureHeaterMsg m;
      m.heater = in.u8();
      m.sample_period_ticks = in.u16() | (static_cast<uint32_t>(in.u8()) << 16);
      m.samples_per_report = in.u8();
      m.adc_min = in.u16();
      m.adc_max = in.u16();
      m.confirm_timeout_ticks = in.u16() | (static_cast<uint32_t>(in.u8()) << 16);
      m.max_duty = in.u16();
      if (const size_t len = protocol::encode_configure_heater(m, buf, sizeof buf)) host.send(buf, len);
    } else if (op == 13) {
      protocol::SetHeaterMsg m;
      m.heater = in.u8();
      m.duty = in.u16();
      if (const size_t len = protocol::encode_set_heater(m, buf, sizeof buf)) host.send(buf, len);
    } else if (op == 14) {
      protocol::SetFanMsg m;
      m.fan = in.u8();
      m.duty = in.u16();
      if (const size_t len = protocol::encode_set_fan(m, buf, sizeof buf)) host.send(buf, len);
    } else {
      const uint8_t axis = in.u8();
      device::TargetKnot knots[16];
      int64_t clock = mcu->clock_at(host.now_s) + in.u16(), pos = 0;
      const int count = 1 + in.u8() % 16;
      for (int k = 0; k < count; ++k) {
        knots[k] = {clock, pos};
        clock += in.u16();
        pos += 1000 * static_cast<int16_t>(in.u16());
      }
      if (const size_t len = protocol::encode_queue_target(axis, knots, count, buf, sizeof buf))
        host.send(buf, len);
    }
    const device::VirtualMcuStatus& st = mcu->status();
    check(st.num_axes == motors);
    for (int i = 0; i < motors; ++i) check(st.axes[i].queued_runs <= device::VirtualMcu::kMaxRuns);
    for (int i = 0; i < 2; ++i) {
      if (st.stopped || board.heater(i).faulted) check(heaters[i].duty == 0.0);
      check(heaters[i].duty <= board.heater(i).duty / 65535.0 + 1e-12);
    }
  }
  return 0;
}
