// EngineRecording: what the engine reports becomes records (encoder samples only when the reading
// changes, on the joint's clock map; anchors as time_anchor events; servo events), and the
// servo-thread calls allocate nothing.
#include <gtest/gtest.h>

#include <cmath>

#include "recorder/engine_recording.hpp"
#include "recorder/log_reader.hpp"
#include "recorder_test_util.hpp"
#include "tests/common/malloc_counter.hpp"

namespace feedloop::recorder {
namespace {

using testing::ScratchDir;

RecorderOptions options(const std::string& dir) {
  RecorderOptions o;
  o.config.directory = dir;
  o.joints = {{"x", 80.0, 0.001, 72'000'000}, {"y", 80.0, 0.0, 72'000'000}};
  return o;
}

TEST(EngineRecordingTest, RecordsWhatTheEngineReports) {
  ScratchDir dir("engrec");
  VirtualClock clock(5'000'000'000);
  auto rec = Recorder::create(options(dir.str()));
  ASSERT_TRUE(rec.ok()) << rec.error().to_string();
  ASSERT_TRUE((*rec)->start_print("t").ok());
  EngineRecording er(**rec, clock);
  std::array<stepgen::TickMap, engine::kJoints> maps{};
  maps.fill({1000.0, 72e6});
  er.on_clock_maps(maps);
  er.on_time_offset(0.25);
  er.on_origin(0, 0, 160);
  er.on_step_run(0, 500, stepgen::StepRun{100, 2, 10, 1});
  engine::ServoSample s;
  s.encoder_mm = {1.0004, NAN, NAN, NAN};  // 1000.4 counts -> 1000
  for (int k = 0; k < 5; ++k) {  // cycles 0..4; the reading changes at cycle 3
    s.host_time_s = 0.001 * k;
    if (k == 3) s.encoder_mm[0] = 1.002;
    er.on_servo_sample(s);
  }
  er.on_servo_event({engine::ServoEventKind::kLostSteps, 1.0, 0, 0.05});
  er.on_servo_event({engine::ServoEventKind::kDeadlineMiss, 1.5, -1, 0.0042});
  engine::DeviceLoopReport lr;
  lr.joint = 1;
  lr.clock = 123'456'789;
  lr.state = 1;
  lr.e_mm = -0.0123456;  // nm in the record: -12346 (rounded)
  lr.y_mm = 42.5;
  lr.correction_mm = 0.25;
  lr.tick_cost = 950;
  lr.ticks = 1000;
  lr.slips = 1;
  er.on_device_loop_report(lr);
  lr.joint = 7;  // no such joint in this recording: not recorded
  er.on_device_loop_report(lr);
  EXPECT_EQ(er.encoder_samples(), 2u);
  EXPECT_EQ(er.loop_reports(), 1u);
  ASSERT_TRUE((*rec)->end_print().ok());
  auto logs = dir.logs();
  ASSERT_EQ(logs.size(), 1u);
  auto r = LogReader::open(logs[0]);
  ASSERT_TRUE(r.ok());
  std::vector<EncoderRecord> enc;
  std::vector<EventRecord> ev;
  std::vector<LoopReportRecord> loops;
  int runs = 0, origins = 0;
  while (const DecodedRecord* d = r->next()) {
    if (auto* l = std::get_if<LoopReportRecord>(&d->record)) loops.push_back(*l);
    if (auto* e = std::get_if<EncoderRecord>(&d->record)) enc.push_back(*e);
    if (auto* e = std::get_if<EventRecord>(&d->record)) ev.push_back(*e);
    runs += std::holds_alternative<StepRunRecord>(d->record);
    origins += std::holds_alternative<OriginRecord>(d->record);
  }
  EXPECT_EQ(runs, 1);
  EXPECT_EQ(origins, 1);
  ASSERT_EQ(enc.size(), 2u);
  EXPECT_EQ(enc[0].counts, 1000);
  EXPECT_EQ(enc[0].clock, 1000);            // map offset at host time 0
  EXPECT_EQ(enc[1].counts, 1002);
  EXPECT_EQ(enc[1].clock, 1000 + 216000);  // 3 ms at 72 MHz
  ASSERT_EQ(ev.size(), 3u);
  EXPECT_EQ(ev[0].kind, EventKind::time_anchor);
  EXPECT_EQ(ev[0].value, 0.25);
  EXPECT_EQ(ev[0].time_ns, 5'000'000'000);
  EXPECT_EQ(ev[1].kind, EventKind::lost_steps);
  EXPECT_EQ(ev[1].joint, 0);
  EXPECT_EQ(ev[1].value, 0.05);
  EXPECT_EQ(ev[1].text, "lost_steps");
  EXPECT_EQ(ev[2].kind, EventKind::deadline_miss);  // lateness 4.2 ms
  EXPECT_EQ(ev[2].value, 0.0042);
  EXPECT_EQ(ev[2].text, "deadline_miss");
  ASSERT_EQ(loops.size(), 1u);
  EXPECT_EQ(loops[0], (LoopReportRecord{1, 123'456'789, 1, -12346, 42'500'000, 250'000, 950, 1000, 0, 0, 1}));
}

TEST(EngineRecordingTest, ServoThreadCallsAllocateNothing) {
  ScratchDir dir("engrec_rt");
  VirtualClock clock;
  auto rec = Recorder::create(options(dir.str()));
  ASSERT_TRUE(rec.ok());
  ASSERT_TRUE((*rec)->start_print("t").ok());
  EngineRecording er(**rec, clock);
  std::array<stepgen::TickMap, engine::kJoints> maps{};
  maps.fill({0.0, 72e6});
  engine::ServoSample s;
  JointSegment seg;
  seg.duration_s = 0.001;
#ifdef FEEDLOOP_COUNT_MALLOC
  g_mallocs = 0;
  g_counting = true;
#endif
  for (int k = 0; k < 20000; ++k) {
    er.on_clock_maps(maps);
    er.on_step_run(k % 2, 1000 * k, stepgen::StepRun{100, 0, 5, 1});
    er.on_segment(0, seg);
    s.host_time_s = 0.001 * k;
    s.encoder_mm[0] = 0.001 * k;
    er.on_servo_sample(s);
    if (k % 10 == 0) {
      engine::DeviceLoopReport lr;
      lr.joint = (k / 10) % 2;
      lr.clock = 72'000 * k;
      lr.e_mm = 1e-3 * (k % 7);
      er.on_device_loop_report(lr);
    }
    if (k % 1000 == 0) {
      er.on_time_offset(0.1 * k);
      er.on_servo_event({engine::ServoEventKind::kFollowingError, 0.0, 1, 2.5});
    }
  }
#ifdef FEEDLOOP_COUNT_MALLOC
  g_counting = false;
  EXPECT_EQ(g_mallocs.load(), 0);
#endif
  EXPECT_EQ(er.encoder_samples(), 20000u);
  EXPECT_EQ((*rec)->stats().dropped, (std::array<uint64_t, kStreams>{}));
  ASSERT_TRUE((*rec)->end_print().ok());
  // Step runs, segments, encoder samples (20000 each), anchors and events (20 each), and one
  // time_sync per block: nothing lost.
  const RecorderStats st = (*rec)->stats();
  EXPECT_EQ(st.records_written, 3u * 20000u + 2000u + 40u + st.blocks_written);
}

}  // namespace
}  // namespace feedloop::recorder
