// Every record type through the real path (writers -> rings -> recorder -> file -> reader) comes
// back identical, bit for bit; the block codec alone round-trips random values; compactness of
// realistic streams (bytes per record).
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdio>
#include <random>

#include "recorder/block_codec.hpp"
#include "recorder/log_reader.hpp"
#include "recorder/log_summary.hpp"
#include "recorder/recorder.hpp"
#include "recorder_test_util.hpp"

namespace feedloop::recorder {
namespace {

using testing::ScratchDir;
using testing::test_options;

std::vector<Record> read_all(const std::string& path, std::optional<Error>* error = nullptr) {
  auto r = LogReader::open(path);
  EXPECT_TRUE(r.ok()) << (r.ok() ? "" : r.error().to_string());
  std::vector<Record> out;
  if (!r.ok()) return out;
  while (const DecodedRecord* d = r->next()) out.push_back(d->record);
  if (error) *error = r->error();
  EXPECT_FALSE(r->error() && !error) << r->error()->to_string();
  return out;
}

template <class T>
std::vector<T> only(const std::vector<Record>& v) {
  std::vector<T> out;
  for (const Record& r : v)
    if (const T* t = std::get_if<T>(&r)) out.push_back(*t);
  return out;
}

bool same_bits(double a, double b) { return std::bit_cast<uint64_t>(a) == std::bit_cast<uint64_t>(b); }

TEST(RecorderRoundTrip, EveryRecordTypeComesBackExactly) {
  ScratchDir dir("roundtrip");
  auto rec = Recorder::create(test_options(dir.str()));
  ASSERT_TRUE(rec.ok()) << rec.error().to_string();
  Recorder& r = **rec;
  ASSERT_TRUE(r.start_print("round trip").ok());

  r.writer(Stream::io).gcode_line(1'000'000, GcodeSource::socket, "G1 X10.5 Y-3 F6000 ; comment");
  r.writer(Stream::io).gcode_line(1'500'000, GcodeSource::pty, "");
  planner::PlannedMove pm;
  pm.index = 7;
  pm.line = 42;
  pm.start_time_s = 1.25;
  pm.duration_s = 0.0123456789;
  pm.start_mm = {10.0, 20.0, 0.2, 1.5};
  pm.end_mm = {10.5, 19.75, 0.2, 1.51234};
  pm.v_entry_mm_s = 5.0;
  pm.v_cruise_mm_s = 100.0 / 3.0;
  pm.v_exit_mm_s = 7.125;
  pm.accel_mm_s2 = 3000.0;
  r.writer(Stream::planner).move(pm);
  planner::PlannedMove pm2 = pm;
  pm2.index = 8;
  pm2.line = 43;
  pm2.start_time_s = pm.start_time_s + pm.duration_s;
  pm2.start_mm = pm.end_mm;
  pm2.end_mm = {-1e-300, 19.75, 0.4, std::nextafter(1.51234, 2.0)};
  pm2.v_entry_mm_s = pm.v_exit_mm_s;
  r.writer(Stream::planner).move(pm2);
  const JointSegment seg{0.5, 0.001, 12.5, -3.25, 1500.0, -1e6 / 7.0};
  r.writer(Stream::planner).segment(2, seg);
  r.writer(Stream::servo).origin(0, 123456, -800);
  r.writer(Stream::servo).step_run(0, 123456, stepgen::StepRun{1000, -3, 17, 1});
  r.writer(Stream::servo).step_run(0, 123456 + 17 * 1000 - 3 * 17 * 16 / 2, stepgen::StepRun{950, 0, 1, -1});
  r.writer(Stream::servo).step_run(3, -5, stepgen::StepRun{(int64_t{1} << 40), -2'000'000'000, 65535, -1});
  r.writer(Stream::servo).encoder_sample(0, 1000, 12345);
  r.writer(Stream::servo).encoder_sample(0, 2000, 12340);
  r.writer(Stream::servo).encoder_sample(0, 3001, -(int64_t{1} << 50));
  r.writer(Stream::servo).event(EventKind::lost_steps, 2'000'000, 1, 3.5, "joint y lost 3.5 steps");
  r.writer(Stream::servo).event(EventKind::deadline_miss, 2'100'000, -1, 1.5e-4);
  const LoopReportRecord lr1{1, 720'000, 1, -1234, 50'000'123, 987, 812, 10, 0, 1, 0};
  const LoopReportRecord lr2{1, 1'440'000, 2, 7, 50'001'000, -5, 4'000'000'000u, 20, 3, 1, 2};
  r.writer(Stream::servo).loop_report(lr1);
  r.writer(Stream::servo).loop_report(lr2);
  ASSERT_TRUE(r.end_print().ok());

  const auto logs = dir.logs();
  ASSERT_EQ(logs.size(), 1u);
  auto reader = LogReader::open(logs[0]);
  ASSERT_TRUE(reader.ok());
  EXPECT_EQ(reader->header().print_name, "round trip");
  EXPECT_EQ(reader->header().joints, testing::test_joints());
  EXPECT_EQ(reader->header().config_yaml, test_options("").config_yaml);
  const auto all = read_all(logs[0]);

  const auto lines = only<GcodeLineRecord>(all);
  ASSERT_EQ(lines.size(), 2u);
  EXPECT_EQ(lines[0], (GcodeLineRecord{1'000'000, GcodeSource::socket, 28, "G1 X10.5 Y-3 F6000 ; comment"}));
  EXPECT_EQ(lines[1], (GcodeLineRecord{1'500'000, GcodeSource::pty, 0, ""}));

  const auto moves = only<MoveRecord>(all);
  ASSERT_EQ(moves.size(), 2u);
  EXPECT_EQ(moves[0].index, 7u);
  EXPECT_EQ(moves[0].line, 42);
  EXPECT_TRUE(same_bits(moves[0].duration_s, pm.duration_s));
  EXPECT_TRUE(same_bits(moves[0].v_cruise_mm_s, pm.v_cruise_mm_s));
  for (int i = 0; i < 4; ++i) {
    EXPECT_TRUE(same_bits(moves[0].end_mm[i], pm.end_mm[i]));
    EXPECT_TRUE(same_bits(moves[1].end_mm[i], pm2.end_mm[i])) << i;
  }
  EXPECT_EQ(moves[1].index, 8u);
  EXPECT_TRUE(same_bits(moves[1].start_time_s, pm2.start_time_s));

  const auto segs = only<SegmentRecord>(all);
  ASSERT_EQ(segs.size(), 1u);
  EXPECT_EQ(segs[0].joint, 2);
  EXPECT_TRUE(same_bits(segs[0].segment.c3_mm_s3, seg.c3_mm_s3));
  EXPECT_TRUE(same_bits(segs[0].segment.c1_mm_s, seg.c1_mm_s));

  const auto runs = only<StepRunRecord>(all);
  ASSERT_EQ(runs.size(), 3u);
  EXPECT_EQ(runs[0].start_clock, 123456);
  EXPECT_EQ(runs[0].run.add_ticks, -3);
  EXPECT_EQ(runs[0].run.count, 17u);
  EXPECT_EQ(runs[1].run.direction, -1);
  EXPECT_EQ(runs[1].run.interval_ticks, 950);
  EXPECT_EQ(runs[2].joint, 3);
  EXPECT_EQ(runs[2].start_clock, -5);
  EXPECT_EQ(runs[2].run.interval_ticks, int64_t{1} << 40);
  EXPECT_EQ(runs[2].run.add_ticks, -2'000'000'000);
  EXPECT_EQ(runs[2].run.count, 65535u);

  const auto enc = only<EncoderRecord>(all);
  ASSERT_EQ(enc.size(), 3u);
  EXPECT_EQ(enc[2], (EncoderRecord{0, 3001, -(int64_t{1} << 50)}));
  EXPECT_EQ(enc[1], (EncoderRecord{0, 2000, 12340}));
  EXPECT_EQ(only<OriginRecord>(all).at(0), (OriginRecord{0, 123456, -800}));
  // The summary says where the print's first move starts (for `ident fit --start-mm`).
  {
    auto sum = summarize_log(logs[0]);
    ASSERT_TRUE(sum.ok());
    for (size_t i = 0; i < 4; ++i) EXPECT_EQ(sum->first_move_start_mm[i], pm.start_mm[i]) << i;
    const std::string text = format_summary(*sum);
    EXPECT_NE(text.find("moves:      2, the first from X 10.0000 Y 20.0000 Z 0.2000 mm"),
              std::string::npos)
        << text;
  }

  const auto events = only<EventRecord>(all);
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0], (EventRecord{EventKind::lost_steps, 2'000'000, 1, 3.5, "joint y lost 3.5 steps"}));
  EXPECT_EQ(events[1], (EventRecord{EventKind::deadline_miss, 2'100'000, -1, 1.5e-4, ""}));
  EXPECT_GE(only<TimeSyncRecord>(all).size(), 1u);  // every block starts with one
  EXPECT_EQ(only<DropRecord>(all).size(), 0u);
  const auto loops = only<LoopReportRecord>(all);
  ASSERT_EQ(loops.size(), 2u);
  EXPECT_EQ(loops[0], lr1);
  EXPECT_EQ(loops[1], lr2);
  EXPECT_EQ(reader->header().version, kFormatVersion);
}

TEST(RecorderRoundTrip, LongGcodeLineIsCutAndSaysSo) {
  ScratchDir dir("longline");
  auto opt = test_options(dir.str());
  opt.max_gcode_text_bytes = 100;
  auto rec = Recorder::create(opt);
  ASSERT_TRUE(rec.ok());
  ASSERT_TRUE((*rec)->start_print("long").ok());
  const std::string line(5000, 'A');
  (*rec)->writer(Stream::io).gcode_line(5, GcodeSource::file, line);
  ASSERT_TRUE((*rec)->end_print().ok());
  const auto lines = only<GcodeLineRecord>(read_all(dir.logs().at(0)));
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0].text, line.substr(0, 100));
  EXPECT_EQ(lines[0].original_length, 5000u);
  auto sum = summarize_log(dir.logs().at(0));
  ASSERT_TRUE(sum.ok());
  EXPECT_EQ(sum->truncated_lines, 1u);
}

// The codec alone: random records of every kind, many blocks, compared field by field.
TEST(RecorderRoundTrip, RandomRecordsThroughTheBlockCodec) {
  std::mt19937_64 rng(12345);
  std::uniform_int_distribution<int64_t> any64;
  std::uniform_real_distribution<double> real(-1e4, 1e4);
  auto rnd_double = [&]() {
    switch (rng() % 4) {
      case 0: return real(rng);
      case 1: return std::bit_cast<double>(rng() & 0x7FEFFFFFFFFFFFFFull);  // any finite bit pattern
      case 2: return 0.0;
      default: return -0.0;
    }
  };
  for (int block = 0; block < 50; ++block) {
    BlockEncoder enc;
    std::vector<Record> in;
    for (int i = 0; i < 200; ++i) {
      const int j = static_cast<int>(rng() % kMaxJoints);
      Record r;
      switch (rng() % 10) {
        case 0: r = GcodeLineRecord{any64(rng), GcodeSource::api, 3, "abc"}; break;
        case 1: {
          MoveRecord m;
          m.index = rng();
          m.line = static_cast<int32_t>(rng());
          m.start_time_s = rnd_double();
          m.duration_s = rnd_double();
          for (int a = 0; a < 4; ++a) m.start_mm[a] = rnd_double(), m.end_mm[a] = rnd_double();
          m.v_entry_mm_s = rnd_double();
          m.v_cruise_mm_s = rnd_double();
          m.v_exit_mm_s = rnd_double();
          m.accel_mm_s2 = rnd_double();
          r = m;
          break;
        }
        case 2: r = SegmentRecord{j, JointSegment{rnd_double(), rnd_double(), rnd_double(), rnd_double(), rnd_double(), rnd_double()}}; break;
        case 3:
          r = StepRunRecord{j, any64(rng),
                            stepgen::StepRun{any64(rng), static_cast<int32_t>(rng()), static_cast<uint32_t>(rng()),
                                             static_cast<int8_t>(rng() % 2 ? 1 : -1)}};
          break;
        case 4: r = EncoderRecord{j, any64(rng), any64(rng)}; break;
        case 5: r = OriginRecord{j, any64(rng), any64(rng)}; break;
        case 6: r = EventRecord{static_cast<EventKind>(rng() % kEventKinds), any64(rng), static_cast<int32_t>(rng() % 9) - 1, rnd_double(), "e"}; break;
        case 7: r = DropRecord{static_cast<Stream>(rng() % kStreams), rng()}; break;
        case 8:
          r = LoopReportRecord{j, any64(rng), static_cast<uint8_t>(rng() % 4), any64(rng), any64(rng), any64(rng),
                               static_cast<uint32_t>(rng()), rng(), rng(), rng(), rng()};
          break;
        default: r = TimeSyncRecord{any64(rng), any64(rng)}; break;
      }
      enc.any(r);
      in.push_back(r);
    }
    std::vector<DecodedRecord> out;
    ASSERT_TRUE(decode_block(enc.body().data(), enc.body().size(), 0, enc.records(), out).ok());
    ASSERT_EQ(out.size(), in.size());
    for (size_t i = 0; i < in.size(); ++i) {
      ASSERT_EQ(in[i].index(), out[i].record.index());
      // Compare the encodings: a lossless round trip re-encodes to the same bytes.
      BlockEncoder a, b;
      a.any(in[i]);
      b.any(out[i].record);
      ASSERT_EQ(a.body(), b.body()) << "record " << i << " of block " << block;
    }
    // And the whole block re-encodes identically (the prediction state evolves the same way).
    BlockEncoder again;
    for (const DecodedRecord& d : out) again.any(d.record);
    ASSERT_EQ(again.body(), enc.body());
  }
}

// Bytes per record of realistic streams: compressed step runs of trapezoid moves, a 1 kHz
// encoder, planned moves of a sliced print's kind.
TEST(RecorderRoundTrip, CompactEncoding) {
  const auto runs = testing::trapezoid_runs(200, 80.0, 72e6);
  ASSERT_GT(runs.size(), 1000u);
  BlockEncoder enc;
  uint64_t steps = 0;
  for (const auto& r : runs) {
    enc.step_run(StepRunRecord{0, r.start_clock, r.run});
    steps += r.run.count;
  }
  const double bytes_per_run = static_cast<double>(enc.body().size()) / static_cast<double>(runs.size());
  const double bytes_per_step = static_cast<double>(enc.body().size()) / static_cast<double>(steps);
  std::printf("step runs: %zu runs, %llu steps, %.2f bytes/run, %.3f bytes/step\n", runs.size(),
              static_cast<unsigned long long>(steps), bytes_per_run, bytes_per_step);
  RecordProperty("bytes_per_step_run", std::to_string(bytes_per_run));
  EXPECT_LT(bytes_per_run, 8.0);    // raw StepRunRecord is 32 bytes
  EXPECT_LT(bytes_per_step, 0.25);  // Klipper's wire format: ~0.58 bytes/step (ANCHORS.md)

  // Encoder at 1 kHz (72 MHz MCU clock, +-2 ticks jitter), a carriage moving at up to 100 mm/s
  // seen with 0.49 um counts.
  BlockEncoder e2;
  std::mt19937 rng(7);
  int64_t clock = 0;
  for (int i = 0; i < 10000; ++i) {
    clock += 72000 + static_cast<int64_t>(rng() % 5) - 2;
    const double pos_mm = 50.0 + 40.0 * std::sin(i * 0.0025);
    e2.encoder(EncoderRecord{1, clock, static_cast<int64_t>(pos_mm / 0.00049)});
  }
  const double bytes_per_sample = static_cast<double>(e2.body().size()) / 10000.0;
  std::printf("encoder: %.2f bytes/sample\n", bytes_per_sample);
  EXPECT_LT(bytes_per_sample, 5.0);  // raw EncoderRecord is 24 bytes

  // Moves: a polyline of XY moves with extrusion; unchanged axes and chained values are ~1 byte.
  BlockEncoder e3;
  MoveRecord m;
  for (int i = 0; i < 1000; ++i) {
    m.index = static_cast<uint64_t>(i);
    m.line = 100 + i;
    m.start_time_s += m.duration_s;
    m.duration_s = 0.01 + 0.001 * (i % 7);
    m.start_mm = m.end_mm;
    m.end_mm = {100.0 + 20.0 * std::cos(i * 0.1), 100.0 + 20.0 * std::sin(i * 0.1), 0.2, m.end_mm[3] + 0.0331};
    m.v_entry_mm_s = m.v_exit_mm_s;
    m.v_cruise_mm_s = 60.0;
    m.v_exit_mm_s = 20.0 + (i % 3);
    m.accel_mm_s2 = 3000.0;
    e3.move(m);
  }
  const double bytes_per_move = static_cast<double>(e3.body().size()) / 1000.0;
  std::printf("moves: %.2f bytes/move\n", bytes_per_move);
  EXPECT_LT(bytes_per_move, 60.0);  // raw MoveRecord is 128 bytes
}

}  // namespace
}  // namespace feedloop::recorder
