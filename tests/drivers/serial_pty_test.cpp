// The real serial path end to end: McuSession over SerialTransport (Boost.Asio) to
// feedloop-vmcu running as its own process on a pseudo-terminal, in real time. Every step must be
// executed exactly once, in order (the device's step hash equals the hash of what was sent).
#include <gtest/gtest.h>

#include <random>
#include <thread>
#include <vector>

#include "core/clock.hpp"
#include "drivers/device/virtual_mcu.hpp"
#include "drivers/host/mcu_session.hpp"
#include "drivers/stepgen/run_codec.hpp"
#include "drivers/stepgen/step_batcher.hpp"
#include "drivers/stepgen/step_compressor.hpp"
#include "drivers/stepgen/step_generator.hpp"
#include "drivers/transport/serial_transport.hpp"
#include "segment_streams.hpp"
#include "vmcu_process.hpp"

namespace feedloop::drivers {
namespace {

const std::string kVmcu = std::string(FEEDLOOP_BINARY_DIR) + "/drivers/feedloop-vmcu";

struct Collect final : stepgen::BatchSink {
  McuSession* session = nullptr;
  uint64_t hash = device::kStepHashSeed, steps = 0;
  void on_batch(const stepgen::StepBatch& b) override {
    stepgen::RunDecoder d;
    d.begin(b.body, b.body_bytes);
    int64_t p = d.first_clock();
    stepgen::StepRun r;
    while (!d.done() && d.next(r)) {
      for (uint32_t k = 1; k <= r.count; ++k) hash = device::step_hash_update(hash, stepgen::run_step_clock(p, r, k), r.direction);
      steps += r.count;
      p = stepgen::run_end_clock(p, r);
    }
    session->queue_steps(b);
  }
};

class SerialPtyMotion : public ::testing::TestWithParam<std::vector<std::string>> {};

TEST_P(SerialPtyMotion, EveryStepExactlyOnce) {
  testing::VmcuProcess vmcu;
  std::vector<std::string> args{"--name", "pty-x", "--drift-ppm", "50"};
  args.insert(args.end(), GetParam().begin(), GetParam().end());
  ASSERT_TRUE(vmcu.start(kVmcu, args)) << vmcu.error();
  SerialTransport transport(vmcu.pty());
  McuSessionParams sp;
  sp.name = "pty-x";
  McuSession session(sp, transport);
  MonotonicClock clock;
  const int64_t t0 = clock.now_ns();
  auto now = [&] { return seconds_from_ns(clock.now_ns() - t0); };
  auto pump = [&](double until_s) {
    while (now() < until_s) {
      session.poll(now());
      transport.poll(now(), 0.5e-3);
    }
  };
  ASSERT_TRUE(session.start(now()).ok()) << session.error()->message;
  pump(2.0);
  ASSERT_TRUE(session.ready()) << (session.error() ? session.error()->message : "not ready");

  // ~2 s of moves starting 0.3 s from now, fed 0.5 s ahead, runs closed 0.25 s before due.
  std::mt19937_64 rng(5);
  auto segs = testing::trapezoid_stream(rng, 20);
  const double start = now() + 0.3;
  for (auto& s : segs) s.t0_s += start;
  Collect col;
  col.session = &session;
  stepgen::StepBatcher batcher;
  batcher.configure(0, 200, &col);
  stepgen::StepCompressor comp;
  comp.configure({100.0, 65535}, &batcher);
  stepgen::StepGenerator gen;
  const stepgen::TickMap map = session.tick_map();
  gen.configure(80.0, map, &comp);
  comp.reset(static_cast<int64_t>(map.ticks(now())), map.ticks(now()));
  session.set_enabled(true);
  size_t next = 0;
  const double end = segs.back().end_s();
  while (now() < end + 0.2) {
    while (next < segs.size() && segs[next].t0_s < now() + 0.5) gen.add_segment(segs[next++]);
    gen.flush();
    const auto deadline = static_cast<int64_t>(map.ticks(now() + 0.25));
    comp.flush_if_due(deadline);
    batcher.flush_if_due(deadline);
    if (next == segs.size()) {
      comp.flush();
      batcher.flush();
    }
    pump(now() + 1e-3);
  }
  session.request_status();
  pump(now() + 0.3);
  for (const auto& e : session.take_events()) std::printf("event: %s\n", e.c_str());
  ASSERT_TRUE(session.last_status().has_value());
  const DeviceStatus st = *session.last_status();
  std::printf("pty: %llu steps sent, %llu executed, %llu frames, %llu bytes written, %llu retransmitted\n",
              (unsigned long long)col.steps, (unsigned long long)st.steps_executed,
              (unsigned long long)session.frames_written(), (unsigned long long)session.bytes_written(),
              (unsigned long long)session.link_stats().retransmitted);
  EXPECT_GT(col.steps, 5000u);
  EXPECT_EQ(st.steps_executed, col.steps);
  EXPECT_EQ(st.step_hash, col.hash);
  EXPECT_FALSE(st.stopped);
  EXPECT_EQ(session.state(), McuState::kReady);
}

// Clean, and with faults injected by feedloop-vmcu on the pty in both directions.
INSTANTIATE_TEST_SUITE_P(Pty, SerialPtyMotion,
                         ::testing::Values(std::vector<std::string>{},
                                           std::vector<std::string>{"--drop", "0.05", "--corrupt", "0.05",
                                                                    "--duplicate", "0.05", "--seed", "3"}),
                         [](const auto& tp) { return tp.param.empty() ? std::string("clean") : std::string("faults"); });

TEST(SerialPty, VersionMismatchRefused) {
  testing::VmcuProcess vmcu;
  ASSERT_TRUE(vmcu.start(kVmcu, {"--protocol-version", "9"})) << vmcu.error();
  SerialTransport transport(vmcu.pty());
  McuSession session({}, transport);
  MonotonicClock clock;
  const int64_t t0 = clock.now_ns();
  ASSERT_TRUE(session.start(0.0).ok());
  while (seconds_from_ns(clock.now_ns() - t0) < 1.0 && session.state() != McuState::kFailed) {
    session.poll(seconds_from_ns(clock.now_ns() - t0));
    transport.poll(0, 1e-3);
  }
  ASSERT_EQ(session.state(), McuState::kFailed);
  EXPECT_NE(session.error()->message.find("protocol version 9"), std::string::npos) << session.error()->message;
}

TEST(SerialPty, MissingPortIsAClearError) {
  SerialTransport t("/dev/feedloop-no-such-port");
  const Status st = t.open();
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().message.find("/dev/feedloop-no-such-port"), std::string::npos);
  EXPECT_NE(st.error().message.find("plugged in"), std::string::npos) << st.error().message;
}

}  // namespace
}  // namespace feedloop::drivers
