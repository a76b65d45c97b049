// The real-time side: record_*() never allocates (global operator new is counted), never blocks,
// drops with a counter when the ring is full (and the log says so), and the SPSC ring keeps every
// record intact and in order across wrap-arounds with a concurrent producer and consumer.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>
#include <thread>

#include "recorder/byte_ring.hpp"
#include "recorder/log_reader.hpp"
#include "recorder/log_summary.hpp"
#include "recorder/recorder.hpp"
#include "recorder_test_util.hpp"

namespace {
std::atomic<uint64_t> g_allocations{0};
}

// Counting replacements of the global allocation functions (this test binary only).
void* operator new(std::size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

namespace feedloop::recorder {
namespace {

using testing::ScratchDir;
using testing::test_options;

void record_one_of_each(Recorder& r, int i) {
  const std::string_view text = "G1 X12.345 Y67.89 E0.0123 F1800";
  r.writer(Stream::io).gcode_line(i, GcodeSource::socket, text);
  planner::PlannedMove m;
  m.index = static_cast<uint64_t>(i);
  r.writer(Stream::planner).move(m);
  r.writer(Stream::planner).segment(i % 4, JointSegment{0.001 * i, 0.001, 1.0, 2.0, 3.0, 4.0});
  r.writer(Stream::servo).step_run(i % 4, 1000 * i, stepgen::StepRun{1000, 1, 10, 1});
  r.writer(Stream::servo).encoder_sample(0, 1000 * i, i);
  r.writer(Stream::servo).origin(1, 1000 * i, i);
  r.writer(Stream::servo).event(EventKind::deadline_miss, i, -1, 1e-5, "late");
}

TEST(RecorderRing, RecordCallsNeverAllocate) {
  ScratchDir dir("noalloc");
  auto rec = Recorder::create(test_options(dir.str()));
  ASSERT_TRUE(rec.ok());
  Recorder& r = **rec;
  ASSERT_TRUE(r.start_print("noalloc").ok());
  record_one_of_each(r, 0);  // warm up
  const uint64_t before = g_allocations.load();
  for (int i = 1; i <= 500; ++i) record_one_of_each(r, i);
  // Past capacity too: the drop path must not allocate either.
  for (int i = 0; i < 20000; ++i) r.writer(Stream::io).gcode_line(i, GcodeSource::pty, "G1 X1");
  const uint64_t after = g_allocations.load();
  EXPECT_EQ(after - before, 0u) << "record_*() allocated";
  EXPECT_GT(r.writer(Stream::io).dropped(), 0u);
  ASSERT_TRUE(r.end_print().ok());
}

TEST(RecorderRing, FullRingDropsWithACounterAndTheLogSaysSo) {
  ScratchDir dir("drops");
  auto opt = test_options(dir.str());
  opt.servo_ring_bytes = 4096;  // 4096 / 40 bytes per step run entry: ~100 fit
  auto rec = Recorder::create(opt);
  ASSERT_TRUE(rec.ok());
  Recorder& r = **rec;
  ASSERT_TRUE(r.start_print("drops").ok());
  int64_t clock = 0;
  const int pushed = 1000;
  for (int i = 0; i < pushed; ++i) {
    r.writer(Stream::servo).step_run(0, clock, stepgen::StepRun{100, 0, 1, 1});
    clock += 100;
  }
  const uint64_t dropped = r.writer(Stream::servo).dropped();
  const size_t per_entry = 8 + sizeof(StepRunRecord);
  EXPECT_EQ(static_cast<uint64_t>(pushed) - dropped, 4096 / per_entry);  // exactly what fits
  ASSERT_TRUE(r.end_print().ok());
  EXPECT_EQ(r.stats().dropped[static_cast<size_t>(Stream::servo)], dropped);

  auto sum = summarize_log(dir.logs().at(0));
  ASSERT_TRUE(sum.ok());
  EXPECT_EQ(sum->dropped[static_cast<size_t>(Stream::servo)], dropped);
  EXPECT_EQ(sum->joints[0].step_runs, static_cast<uint64_t>(pushed) - dropped);
  EXPECT_NE(format_summary(*sum).find("rings were full"), std::string::npos);
}

TEST(RecorderRing, DisabledRecorderRecordsNothing) {
  ScratchDir dir("disabled");
  auto opt = test_options(dir.str());
  opt.config.enabled = false;
  auto rec = Recorder::create(opt);
  ASSERT_TRUE(rec.ok());
  ASSERT_TRUE((*rec)->start_print("off").ok());
  record_one_of_each(**rec, 1);
  ASSERT_TRUE((*rec)->end_print().ok());
  EXPECT_TRUE(dir.logs().empty());
  EXPECT_EQ((*rec)->writer(Stream::servo).dropped(), 0u);
}

TEST(RecorderRing, BadJointIndexIsRejectedAndCounted) {
  ScratchDir dir("badjoint");
  auto rec = Recorder::create(test_options(dir.str()));
  ASSERT_TRUE(rec.ok());
  (*rec)->writer(Stream::servo).step_run(4, 0, stepgen::StepRun{1, 0, 1, 1});  // 4 joints: 0..3
  (*rec)->writer(Stream::servo).encoder_sample(-1, 0, 0);
  EXPECT_EQ((*rec)->stats().rejected, 2u);
}

// Variable-length records through a small ring with a concurrent consumer: every record arrives,
// in order, intact, across thousands of wrap-arounds; drops are exactly the failed pushes.
TEST(RecorderRing, ConcurrentProducerConsumerKeepsOrderAndContent) {
  ByteRing ring(1024);
  constexpr uint32_t kRecords = 200000;
  std::atomic<bool> done{false};
  uint64_t failed = 0;
  std::vector<uint32_t> accepted;
  accepted.reserve(kRecords);
  std::thread producer([&] {
    uint8_t payload[64];
    for (uint32_t i = 0; i < kRecords; ++i) {
      const size_t len = 4 + (i * 7) % 57;  // 4..60 bytes
      std::memcpy(payload, &i, 4);
      for (size_t k = 4; k < len; ++k) payload[k] = static_cast<uint8_t>(i + k);
      // Most records are retried until they fit (the consumer frees space), every fourth is
      // dropped when the ring is full.
      bool ok = ring.try_push(static_cast<uint8_t>(i % 200), payload, len);
      while (!ok && i % 4 != 0) {
        std::this_thread::yield();
        ok = ring.try_push(static_cast<uint8_t>(i % 200), payload, len);
      }
      if (ok) accepted.push_back(i);
      else ++failed;
    }
    done.store(true);
  });
  std::vector<uint32_t> got;
  bool intact = true;
  auto consume = [&](uint8_t type, const uint8_t* p, size_t n) {
    uint32_t i = 0;
    std::memcpy(&i, p, 4);
    if (type != i % 200 || n != 4 + (i * 7) % 57) intact = false;
    for (size_t k = 4; k < n; ++k)
      if (p[k] != static_cast<uint8_t>(i + k)) intact = false;
    got.push_back(i);
  };
  while (!done.load()) ring.drain(consume);
  producer.join();
  ring.drain(consume);
  EXPECT_TRUE(intact);
  EXPECT_EQ(got, accepted);
  EXPECT_EQ(got.size() + failed, kRecords);
  EXPECT_GE(got.size(), kRecords * 3 / 4);  // ~8000 trips around the 1 KiB ring
  EXPECT_EQ(ring.used(), 0u);
}

}  // namespace
}  // namespace feedloop::recorder
