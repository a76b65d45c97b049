// The recorder under its real threading: three producer threads (I/O, planner, servo) push as
// fast as they can while the recorder thread drains; nothing deadlocks, every record pushed is
// either in the file or counted as dropped, and each stream's records arrive in order. The taps
// record exactly what they forward.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "recorder/log_reader.hpp"
#include "recorder/recorder.hpp"
#include "recorder/run_tap.hpp"
#include "recorder/trace_export.hpp"
#include "recorder_test_util.hpp"

namespace feedloop::recorder {
namespace {

// Three producers paced at 20 records per ms each (~1 s) and the recorder thread draining: what
// arrived, in order, with every record either in the file or counted as dropped.
struct ThreeProducersResult {
  uint64_t lines = 0, moves = 0, samples = 0;
  RecorderStats stats;
};
constexpr int kEach = 20000;

void run_three_producers(ThreeProducersResult* out) {
  testing::ScratchDir dir("threads");
  auto opt = testing::test_options(dir.str());
  opt.io_ring_bytes = 1 << 18;  // room for ~10 drain periods at the pace below
  opt.planner_ring_bytes = 1 << 20;
  opt.servo_ring_bytes = 1 << 18;
  auto rec = Recorder::create(opt);
  ASSERT_TRUE(rec.ok());
  Recorder& r = **rec;
  ASSERT_TRUE(r.start_print("threads").ok());
  r.start_thread();
  std::thread io([&] {
    for (int i = 0; i < kEach; ++i) {
      r.writer(Stream::io).gcode_line(i, GcodeSource::socket, "G1 X1 Y2");
      if (i % 20 == 19) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  });
  std::thread planner([&] {
    for (int i = 0; i < kEach; ++i) {
      planner::PlannedMove m;
      m.index = static_cast<uint64_t>(i);
      r.writer(Stream::planner).move(m);
      if (i % 20 == 19) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  });
  std::thread servo([&] {
    for (int i = 0; i < kEach; ++i) {
      r.writer(Stream::servo).encoder_sample(i % 4, i, i);
      if (i % 20 == 19) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  });
  io.join();
  planner.join();
  servo.join();
  ASSERT_TRUE(r.end_print().ok());
  r.stop_thread();
  const RecorderStats st = r.stats();

  auto reader = LogReader::open(dir.logs().at(0));
  ASSERT_TRUE(reader.ok());
  uint64_t lines = 0, moves = 0, samples = 0;
  int64_t last_line = -1, last_sample = -1;
  uint64_t last_move = 0;
  bool ordered = true;
  while (const DecodedRecord* d = reader->next()) {
    if (const auto* g = std::get_if<GcodeLineRecord>(&d->record)) {
      ordered &= g->time_ns > last_line;
      last_line = g->time_ns;
      ++lines;
    } else if (const auto* m = std::get_if<MoveRecord>(&d->record)) {
      ordered &= moves == 0 || m->index > last_move;
      last_move = m->index;
      ++moves;
    } else if (const auto* e = std::get_if<EncoderRecord>(&d->record)) {
      ordered &= e->clock > last_sample;
      last_sample = e->clock;
      ++samples;
    }
  }
  EXPECT_FALSE(reader->error().has_value());
  EXPECT_TRUE(ordered);
  EXPECT_EQ(lines + st.dropped[0], static_cast<uint64_t>(kEach));
  EXPECT_EQ(moves + st.dropped[1], static_cast<uint64_t>(kEach));
  EXPECT_EQ(samples + st.dropped[2], static_cast<uint64_t>(kEach));
  std::printf("dropped: io %llu, planner %llu, servo %llu of %d each\n", static_cast<unsigned long long>(st.dropped[0]),
              static_cast<unsigned long long>(st.dropped[1]), static_cast<unsigned long long>(st.dropped[2]), kEach);
  *out = {lines, moves, samples, st};
}

TEST(RecorderThreads, ThreeProducersAndTheRecorderThread) {
  ThreeProducersResult r;
  run_three_producers(&r);
}

// The drain keeps pace: at most a tenth dropped. On the wall clock with the recorder thread given
// its share of a core (label realtime: run alone; beside other tests and compilers on a 2-core
// machine it dropped 15 %).
TEST(RecorderThreads, TheDrainKeepsPaceWithThreeProducers) {
  ThreeProducersResult r;
  run_three_producers(&r);
  EXPECT_GE(r.lines + r.moves + r.samples, static_cast<uint64_t>(kEach) * 3 * 9 / 10);
}

// One servo producer, unpaced, into a ring of ~100 encoder records, with a recorder thread that
// drains only every 10 s unless woken: what reached the file, what was dropped, how often a push
// waited, and what the trace export makes of it.
struct FullRingResult {
  uint64_t samples = 0, dropped = 0, waited = 0, trace_dropped = 0;
  bool ordered = true, warned = false;
};

FullRingResult push_into_a_small_ring(bool wait_for_room) {
  constexpr int kSamples = 20000;
  testing::ScratchDir dir("fullring");
  auto opt = testing::test_options(dir.str());
  opt.servo_ring_bytes = 1 << 12;
  opt.drain_period_s = 10.0;
  auto rec = Recorder::create(opt);
  EXPECT_TRUE(rec.ok());
  Recorder& r = **rec;
  r.set_wait_for_room(wait_for_room);
  EXPECT_TRUE(r.start_print("fullring").ok());
  r.start_thread();
  for (int i = 0; i < kSamples; ++i)
    r.writer(Stream::servo).encoder_sample(0, int64_t{1000} * i, i);  // 1 kHz
  EXPECT_TRUE(r.end_print().ok());
  r.stop_thread();
  FullRingResult out;
  out.dropped = r.stats().dropped[2];
  out.waited = r.stats().waited;
  auto reader = LogReader::open(dir.logs().at(0));
  EXPECT_TRUE(reader.ok());
  int64_t last = -1;
  while (const DecodedRecord* d = reader->next())
    if (const auto* e = std::get_if<EncoderRecord>(&d->record)) {
      out.ordered &= e->clock > last;
      last = e->clock;
      ++out.samples;
    }
  EXPECT_EQ(out.samples + out.dropped, static_cast<uint64_t>(kSamples));
  auto t = build_trace(dir.logs(), ExportOptions{});
  EXPECT_TRUE(t.ok());
  if (t.ok()) {
    out.trace_dropped = t->servo_records_dropped;
    for (const std::string& c : t->comments) out.warned |= c.find("dropped") != std::string::npos;
  }
  return out;
}

// Virtual time (the daemon's --virtual-time, `feedloop calibrate`): a full ring waits for the
// recorder thread, so a recording is whole however far the producer runs ahead.
TEST(RecorderThreads, AFullRingWaitsForRoomAndLosesNothingInVirtualTime) {
  const FullRingResult r = push_into_a_small_ring(true);
  EXPECT_EQ(r.dropped, 0u);
  EXPECT_EQ(r.samples, 20000u);
  EXPECT_GT(r.waited, 0u);  // the ring did fill: the waiting was exercised
  EXPECT_TRUE(r.ordered);
  EXPECT_EQ(r.trace_dropped, 0u);
  EXPECT_FALSE(r.warned);
}

// Real time never waits: the same producer loses records, counted, and the trace export says how
// many (feedloop calibrate refuses such a trace).
TEST(RecorderThreads, AFullRingDropsInRealTimeAndTheTraceSaysHowMany) {
  const FullRingResult r = push_into_a_small_ring(false);
  EXPECT_GT(r.dropped, 0u);
  EXPECT_EQ(r.waited, 0u);
  EXPECT_TRUE(r.ordered);
  EXPECT_EQ(r.trace_dropped, r.dropped);
  EXPECT_TRUE(r.warned);
}

TEST(RecorderThreads, RunTapRecordsExactlyWhatItForwards) {
  testing::ScratchDir dir("tap");
  auto rec = Recorder::create(testing::test_options(dir.str()));
  ASSERT_TRUE(rec.ok());
  ASSERT_TRUE((*rec)->start_print("tap").ok());
  testing::CollectRuns forwarded;
  RunTap tap(&(*rec)->writer(Stream::servo), 2, &forwarded);
  stepgen::StepCompressor comp;
  comp.configure(stepgen::StepCompressorParams{360.0, 65535}, &tap);
  comp.reset(0, 0.0);
  stepgen::StepGenerator gen;
  gen.configure(400.0, stepgen::TickMap{0.0, 72e6}, &comp);
  gen.set_position_mm(0.0);
  gen.add_segment(JointSegment{0.0, 0.2, 0.0, 0.0, 50.0, 0.0});  // z: 1 mm in 0.2 s
  gen.flush();
  comp.flush();
  ASSERT_TRUE((*rec)->end_print().ok());
  ASSERT_GT(forwarded.runs.size(), 3u);
  auto reader = LogReader::open(dir.logs().at(0));
  ASSERT_TRUE(reader.ok());
  size_t i = 0;
  while (const DecodedRecord* d = reader->next()) {
    const auto* s = std::get_if<StepRunRecord>(&d->record);
    if (!s) continue;
    ASSERT_LT(i, forwarded.runs.size());
    EXPECT_EQ(s->joint, 2);
    EXPECT_EQ(s->start_clock, forwarded.runs[i].start_clock);
    EXPECT_EQ(s->run.interval_ticks, forwarded.runs[i].run.interval_ticks);
    EXPECT_EQ(s->run.add_ticks, forwarded.runs[i].run.add_ticks);
    EXPECT_EQ(s->run.count, forwarded.runs[i].run.count);
    ++i;
  }
  EXPECT_EQ(i, forwarded.runs.size());
}

}  // namespace
}  // namespace feedloop::recorder
