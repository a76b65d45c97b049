// libFuzzer target for the host side of the MCU link: drivers::McuSession decoding whatever a
// device sends. The input plays the device behind a fake Transport. The harness's device has a
// real protocol::ReliableLink, so well-formed messages arrive in order and the host's frames are
// acknowledged; other operations put noise, forged frames and link drops on the wire.
// Operations (fuzz_input.hpp), each followed by a poll of the session:
//   0 N bytes[N]       the device sends a message (payload = bytes) over its link
//   1 N bytes[N]       raw bytes on the wire
//   2 F S S A A N b[N] a frame with flags F, seq, ack (little endian) and a correct CRC
//   3 T                T * 0.5 ms pass
//   4 K ...            the host calls (K % 6): start, queue_steps (axis, N, body[N]),
//                      set_enabled, emergency_stop, request_status, take_encoder_samples
//   5 K C*8            the device answers the newest clock query: K&1 with the true clock plus
//                      a small error C (int16), else with the 8 bytes C as the clock
//   6 K                link maintenance: the device polls its link (retransmits)
//   7 K                the link drops; K&1: re-opening fails until the next operation 7
//   8 K ...            the device sends a protocol v2 LOOP_REPORT (K even) or LOOP_EVENT with
//                      every field from the input (8 bytes per 64-bit field)
//   9 K ...            the host calls: take_loop_reports / take_loop_events (K&1), or
//                      queue_message(N, bytes[N]) (K&2)
// Invariants (trap): every host write is one whole frame with a valid CRC; a failed session has an
// error that names the MCU; a ready session has a clock rate > 0, 1 to kMaxAxes motors and a
// finite clock estimate; no more than kSampleCapacity encoder samples are kept.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "drivers/device/virtual_mcu.hpp"  // kMaxAxes
#include "drivers/host/mcu_session.hpp"
#include "drivers/protocol/loop_messages.hpp"
#include "drivers/protocol/messages.hpp"
#include "drivers/protocol/reliable_link.hpp"
#include "fuzz/fuzz_input.hpp"

namespace {

using namespace feedloop;
using fuzz::check;
using fuzz::FuzzInput;

// The device end of the wire: its link's frames go to `rx`, the host's frames into its link.
class FakeDevice final : public drivers::Transport,
                         private protocol::FrameOutput,
                         private protocol::PayloadHandler {
 public:
  FakeDevice() {
    protocol::LinkParams lp;
    lp.initial_epoch = 5;
    link_.configure(lp, this, this);
  }

  // drivers::Transport (the host's view)
  Status open() override {
    if (refuse_open) return Error{"fuzz device: cannot open"};
    connected_ = true;
    return Status::Ok();
  }
  void close() override { connected_ = false; }
  bool connected() const override { return connected_; }
  Status write(const uint8_t* data, size_t n) override {
    if (!connected_) return Error{"fuzz device: link down"};
    // One whole frame per write, with a valid CRC.
    check(n >= protocol::kFrameOverhead && n <= protocol::kMaxFrame);
    protocol::FrameDecoder dec;
    check(dec.feed(data, n) == n);
    protocol::FrameView f;
    check(dec.next(f));
    check(f.len + protocol::kFrameOverhead == n);
    link_.on_bytes(data, n, now_ns);
    return Status::Ok();
  }
  Result<size_t> read(uint8_t* buf, size_t cap) override {
    if (!connected_) return Error{"fuzz device: link down"};
    const size_t n = std::min(cap, rx.size() - rx_pos_);
    if (n > 0) std::memcpy(buf, rx.data() + rx_pos_, n);
    rx_pos_ += n;
    if (rx_pos_ == rx.size()) rx.clear(), rx_pos_ = 0;
    return n;
  }
  void poll(double, double) override {}
  std::string describe() const override { return "fuzz device"; }

  void send(const uint8_t* p, size_t n) { link_.send(p, n, now_ns); }
  void poll_link() { link_.poll(now_ns); }
  void put(const uint8_t* p, size_t n) { rx.insert(rx.end(), p, p + n); }

  std::vector<uint8_t> rx;
  bool refuse_open = false;
  int64_t now_ns = 0;
  uint64_t last_query_token = 0;
  bool have_query = false;

 private:
  void write_frame(const uint8_t* frame, size_t n) override { put(frame, n); }
  void on_payload(const uint8_t* p, size_t n) override {
    protocol::MsgReader r(p, n);
    if (static_cast<protocol::MsgType>(r.u8()) != protocol::MsgType::kClockQuery) return;
    const uint64_t token = r.var();
    if (r.ok()) last_query_token = token, have_query = true;
  }

  protocol::ReliableLink link_;
  bool connected_ = false;
  size_t rx_pos_ = 0;
};

void check_session(const drivers::McuSession& s) {
  if (s.state() == drivers::McuState::kFailed) {
    check(s.error().has_value());
    check(s.error()->message.find("fuzz-mcu") != std::string::npos);
  }
  if (s.ready()) {
    check(s.mcu_clock_hz() > 0);
    check(s.mcu_axes() >= 1 && s.mcu_axes() <= device::VirtualMcu::kMaxAxes);
    const double f = s.clock().freq_hz();
    check(std::isfinite(f) && f > 0.0);
    const stepgen::TickMap m = s.tick_map();
    check(std::isfinite(m.offset_ticks) && std::isfinite(m.ticks_per_s));
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  FuzzInput in(data, size);
  FakeDevice dev;
  drivers::McuSessionParams params;
  params.name = "fuzz-mcu";
  drivers::McuSession session(params, dev);
  double now_s = 0.0;
  std::vector<drivers::EncoderSample> samples;
  (void)session.start(now_s);
  while (!in.empty()) {
    size_t n = 0;
    const uint8_t op = in.u8() % 10;
    if (op == 0) {
      const uint8_t* p = in.take(in.u8(), n);
      dev.send(p, n);
    } else if (op == 1) {
      const uint8_t* p = in.take(in.u8(), n);
      dev.put(p, n);
    } else if (op == 2) {
      const uint8_t flags = in.u8();
      const uint16_t seq = in.u16(), ack = in.u16();
      const uint8_t* p = in.take(in.u8() % (protocol::kMaxPayload + 1), n);
      uint8_t frame[protocol::kMaxFrame];
      dev.put(frame, protocol::encode_frame(frame, flags, seq, ack, p, n));
    } else if (op == 3) {
      now_s += 0.5e-3 * in.u8();
    } else if (op == 4) {
      switch (in.u8() % 6) {
        case 0:
          (void)session.start(now_s);
          break;
        case 1: {
          stepgen::StepBatch b;
          b.axis = in.u8();
          b.body = in.take(in.u8(), n);
          b.body_bytes = n;
          session.queue_steps(b);
          break;
        }
        case 2:
          session.set_enabled(in.u8() & 1);
          break;
        case 3:
          session.emergency_stop();
          break;
        case 4:
          session.request_status();
          break;
        default:
          check(session.take_encoder_samples(samples) <= drivers::McuSession::kSampleCapacity);
          break;
      }
    } else if (op == 5) {
      const uint8_t kind = in.u8();
      uint64_t clock = 0;
      if (kind & 1) {
        clock = static_cast<uint64_t>(std::llround(now_s * 20e6)) +
                static_cast<uint64_t>(static_cast<int16_t>(in.u16()));
      } else {
        for (int i = 0; i < 8; ++i) clock |= static_cast<uint64_t>(in.u8()) << (8 * i);
      }
      if (dev.have_query) {
        uint8_t buf[32];
        protocol::MsgWriter w(buf, sizeof buf);
        w.u8(static_cast<uint8_t>(protocol::MsgType::kClockResponse))
            .var(dev.last_query_token)
            .var(clock);
        dev.send(buf, w.size());
      }
    } else if (op == 6) {
      dev.poll_link();
    } else if (op == 7) {
      dev.close();
      dev.refuse_open = in.u8() & 1;
    } else if (op == 8) {
      uint8_t buf[protocol::kMaxPayload];
      size_t len = 0;
      if (in.u8() % 2 == 0) {
        protocol::LoopReportMsg m;
        m.axis = in.u8();
        device::LoopReport& r = m.report;
        r.clock = static_cast<int64_t>(in.u64());
        r.state = static_cast<device::LoopState>(in.u8());
        r.r_nm = static_cast<int64_t>(in.u64());
        r.y_nm = static_cast<int64_t>(in.u64());
        const uint32_t e = in.u32(), u = in.u32();
        std::memcpy(&r.e_nm, &e, sizeof e);
        std::memcpy(&r.u_nm, &u, sizeof u);
        r.device_steps = static_cast<int64_t>(in.u64());
        r.max_tick_cost = in.u32();
        r.ticks = in.u64();
        r.deadline_misses = in.u64();
        r.encoder_rejects = in.u64();
        r.slips = in.u64();
        len = protocol::encode_loop_report(m, buf, sizeof buf);
      } else {
        protocol::LoopEventMsg m;
        m.axis = in.u8();
        m.event.kind = static_cast<device::LoopEventKind>(in.u8());
        m.event.clock = static_cast<int64_t>(in.u64());
        m.event.a = static_cast<int64_t>(in.u64());
        m.event.b = static_cast<int64_t>(in.u64());
        len = protocol::encode_loop_event(m, buf, sizeof buf);
      }
      if (len > 0) dev.send(buf, len);
    } else {
      const uint8_t k = in.u8();
      if (k & 2) {
        const uint8_t* p = in.take(in.u8(), n);
        session.queue_message(p, n);
      } else if (k & 1) {
        protocol::LoopEventMsg events[8];
        check(session.take_loop_events(events, 8) <= 8);
      } else {
        protocol::LoopReportMsg reports[8];
        check(session.take_loop_reports(reports, 8) <= 8);
      }
    }
    now_s += 1e-4;
    dev.now_ns = static_cast<int64_t>(now_s * 1e9);
    session.poll(now_s);
    check_session(session);
  }
  check(session.take_encoder_samples(samples) <= drivers::McuSession::kSampleCapacity);
  (void)session.take_events();
  return 0;
}
