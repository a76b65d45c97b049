// Heap allocations on the drivers' steady-state path (what the servo thread runs through
// engine::McuBridge): step batches queued in McuSession and sent through the reliable link, acks,
// clock queries, heartbeats, encoder reports taken with take_encoder_samples(out), the mock
// transport's frame delivery (with and without faults) and the virtual MCU. After a warm-up, a
// few thousand 1 ms periods of steady streaming must allocate nothing. malloc is interposed
// (tests/common/malloc_counter.hpp); skipped under sanitizers, which own malloc.
#include <gtest/gtest.h>

#include <cstdio>
#include <memory>
#include <random>
#include <vector>

#include "drivers/device/virtual_mcu.hpp"
#include "drivers/host/mcu_session.hpp"
#include "drivers/stepgen/run_codec.hpp"
#include "drivers/stepgen/step_batcher.hpp"
#include "drivers/stepgen/step_compressor.hpp"
#include "drivers/stepgen/step_generator.hpp"
#include "drivers/transport/mock_transport.hpp"
#include "segment_streams.hpp"
#include "tests/common/malloc_counter.hpp"

namespace feedloop::drivers {
namespace {

struct CountingMotor final : device::MotorPort {
  int64_t pos = 0;
  uint64_t steps = 0;
  void step(double, int d) override {
    pos += d;
    ++steps;
  }
  void set_enabled(double, bool) override {}
  int64_t read_encoder_counts(double) override { return pos * 25; }
};

// Counts and hashes what is sent (like McuBridge::on_batch) and queues it.
struct Sink final : stepgen::BatchSink {
  McuSession* session = nullptr;
  uint64_t steps = 0, hash = device::kStepHashSeed, batches = 0;
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
    ++batches;
    session->queue_steps(b);
  }
};

struct AllocCase {
  const char* name;
  MockFaults faults;
};

class SessionAlloc : public ::testing::TestWithParam<AllocCase> {};

TEST_P(SessionAlloc, SteadyStreamingAllocatesNothing) {
#ifndef FEEDLOOP_COUNT_MALLOC
  GTEST_SKIP() << "malloc counting needs glibc and no sanitizer";
#else
  CountingMotor motor;
  device::VirtualMcuParams mp;
  mp.drift_ppm = 50.0;
  mp.offset_s = 4.2;
  std::snprintf(mp.name, sizeof mp.name, "alloc-x");
  auto mcu = std::make_unique<device::VirtualMcu>(mp, &motor);
  auto transport = std::make_unique<MockTransport>(*mcu, GetParam().faults, "x");
  McuSessionParams sp;
  sp.name = "x";
  auto session = std::make_unique<McuSession>(sp, *transport);
  double now = 0.0;
  const double period_s = 1e-3, slice_s = 50e-6;  // McuBridge's servo period and I/O slice
  auto period = [&] {
    for (int k = 1; k <= 20; ++k) session->poll(now + k * slice_s);
    now += period_s;
  };
  ASSERT_TRUE(session->start(now).ok());
  while (now < 2.0) period();  // identify, configure, clock burst, sync
  ASSERT_TRUE(session->ready()) << (session->error() ? session->error()->message : "not ready");

  std::mt19937_64 rng(17);
  auto segs = testing::trapezoid_stream(rng, 200);  // far longer than the run: always streaming
  const double start = now + 0.3;
  for (auto& s : segs) s.t0_s += start;
  Sink sink;
  sink.session = session.get();
  stepgen::StepBatcher batcher;
  batcher.configure(0, 200, &sink);
  stepgen::StepCompressor comp;
  comp.configure({100.0, 65535}, &batcher);
  stepgen::StepGenerator gen;
  const stepgen::TickMap map = session->tick_map();
  gen.configure(1600.0, map, &comp);  // 16 microsteps: ~60 k steps/s at full speed
  comp.reset(static_cast<int64_t>(map.ticks(now)), map.ticks(now));
  session->set_enabled(true);
  std::vector<EncoderSample> samples;  // the consumer's buffer, reused
  size_t next = 0;
  uint64_t samples_taken = 0;
  auto cycle = [&] {
    while (next < segs.size() && segs[next].t0_s < now + 0.5) gen.add_segment(segs[next++]);
    gen.flush();
    const auto deadline = static_cast<int64_t>(map.ticks(now + 0.25));
    comp.flush_if_due(deadline);
    batcher.flush_if_due(deadline);
    period();
    samples_taken += session->take_encoder_samples(samples);
  };
  for (int i = 0; i < 1000; ++i) cycle();  // warm-up: 1 s of motion
  const uint64_t steps0 = motor.steps, batches0 = sink.batches, queries0 = session->clock().samples(),
                 frames0 = session->frames_written(), samples0 = samples_taken;
  const int kPeriods = 4000;
  g_mallocs = 0;
  g_counting = true;
  for (int i = 0; i < kPeriods; ++i) cycle();
  g_counting = false;
  const long mallocs = g_mallocs.load();
  const uint64_t steps = motor.steps - steps0, batches = sink.batches - batches0,
                 frames = session->frames_written() - frames0, nsamples = samples_taken - samples0;
  std::printf("%s: %d periods of 1 ms: %llu steps executed, %llu batches, %llu host frames, %llu encoder samples, "
              "%d clock samples; %ld allocations\n",
              GetParam().name, kPeriods, (unsigned long long)steps, (unsigned long long)batches,
              (unsigned long long)frames, (unsigned long long)nsamples,
              session->clock().samples() - static_cast<int>(queries0), mallocs);
  // The window was really streaming: steps, batches, acks and encoder reports flowed.
  EXPECT_GT(steps, 200000u);
  EXPECT_GT(batches, 25u);   // ~1 per 100 ms: compression packs ~9000 steps per batch
  EXPECT_GT(frames, 400u);   // acks of the 100 encoder reports/s, clock queries, heartbeats
  EXPECT_GE(nsamples, 3900u);  // 1 kHz encoder sampling
  EXPECT_EQ(session->state(), McuState::kReady);
  EXPECT_EQ(mallocs, 0);
  // And nothing was lost or doubled: drain and compare the device's step hash.
  gen.flush();
  comp.flush();
  batcher.flush();
  const double drain_end = now + 1.0;
  while (now < drain_end) period();
  const uint64_t sent = sink.steps, sent_hash = sink.hash;
  // Stop feeding; run until the device has executed everything that was sent.
  const double end = now + 25.0;
  while (now < end && motor.steps < sent) period();
  session->request_status();
  for (int i = 0; i < 300; ++i) period();
  ASSERT_TRUE(session->last_status().has_value());
  EXPECT_EQ(session->last_status()->steps_executed, sent);
  EXPECT_EQ(session->last_status()->step_hash, sent_hash);
#endif
}

INSTANTIATE_TEST_SUITE_P(Links, SessionAlloc,
                         ::testing::Values(AllocCase{"clean", MockFaults{}}, AllocCase{"faults", [] {
                                                                               MockFaults f;
                                                                               f.drop = f.corrupt = f.duplicate = 0.02;
                                                                               f.reorder = 0.02;
                                                                               f.delay = 0.01;
                                                                               f.jitter_s = 100e-6;
                                                                               f.seed = 5;
                                                                               return f;
                                                                             }()}),
                         [](const auto& tp) { return std::string(tp.param.name); });

}  // namespace
}  // namespace feedloop::drivers
