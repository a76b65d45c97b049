// Rotation beyond the size cap, deletion beyond keep_files, one file per print, and the step
// stream continuing exactly across the parts of a print.
#include <gtest/gtest.h>

#include <filesystem>

#include "recorder/log_reader.hpp"
#include "recorder/recorder.hpp"
#include "recorder_test_util.hpp"

namespace feedloop::recorder {
namespace {

using testing::ScratchDir;

std::vector<StepRunRecord> runs_in(const std::string& path, LogHeader* header = nullptr) {
  auto r = LogReader::open(path);
  EXPECT_TRUE(r.ok());
  std::vector<StepRunRecord> out;
  if (!r.ok()) return out;
  if (header) *header = r->header();
  while (const DecodedRecord* d = r->next())
    if (const auto* s = std::get_if<StepRunRecord>(&d->record)) out.push_back(*s);
  EXPECT_FALSE(r->error().has_value());
  return out;
}

TEST(RecorderRotation, SizeCapRotatesAndKeepFilesDeletesTheOldest) {
  ScratchDir dir("rotation");
  auto opt = testing::test_options(dir.str());
  opt.config.max_file_size_mb = 4.0 / 1024.0;  // 4 KiB
  opt.config.keep_files = 3;
  opt.block_bytes = 1024;
  auto rec = Recorder::create(opt);
  ASSERT_TRUE(rec.ok());
  Recorder& r = **rec;
  ASSERT_TRUE(r.start_print("rotate me").ok());

  const auto runs = testing::trapezoid_runs(100, 80.0, 1e6);
  ASSERT_GT(runs.size(), 3000u);
  for (size_t i = 0; i < runs.size(); ++i) {
    r.writer(Stream::servo).step_run(1, runs[i].start_clock, runs[i].run);
    if (i % 100 == 99) {
      ASSERT_TRUE(r.poll().ok());
    }
  }
  ASSERT_TRUE(r.end_print().ok());
  const RecorderStats st = r.stats();
  EXPECT_EQ(st.dropped[2], 0u);
  const uint64_t parts = st.files_opened;
  std::printf("%llu parts, %llu deleted, %llu bytes\n", static_cast<unsigned long long>(parts),
              static_cast<unsigned long long>(st.files_deleted), static_cast<unsigned long long>(st.bytes_written));
  EXPECT_GT(parts, 3u);  // ~7 bytes per run: >3000 runs need more than 3 files of 4 KiB
  EXPECT_EQ(st.files_deleted, parts - 3);

  const auto logs = dir.logs();
  ASSERT_EQ(logs.size(), 3u);
  std::vector<StepRunRecord> kept;
  for (size_t i = 0; i < logs.size(); ++i) {
    EXPECT_LE(std::filesystem::file_size(logs[i]), 4u * 1024u) << logs[i];
    LogHeader h;
    const auto part_runs = runs_in(logs[i], &h);
    EXPECT_EQ(h.part, parts - 3 + i);  // the newest parts survive, in name order
    EXPECT_EQ(h.print_name, "rotate me");
    EXPECT_NE(logs[i].find("rotate_me_p"), std::string::npos);
    kept.insert(kept.end(), part_runs.begin(), part_runs.end());
  }
  // The kept parts hold exactly the tail of the stream, without a gap between parts.
  ASSERT_GT(kept.size(), 0u);
  ASSERT_LT(kept.size(), runs.size());
  const size_t skip = runs.size() - kept.size();
  for (size_t i = 0; i < kept.size(); ++i) {
    ASSERT_EQ(kept[i].start_clock, runs[skip + i].start_clock) << i;
    ASSERT_EQ(kept[i].run.interval_ticks, runs[skip + i].run.interval_ticks) << i;
    ASSERT_EQ(kept[i].run.add_ticks, runs[skip + i].run.add_ticks) << i;
    ASSERT_EQ(kept[i].run.count, runs[skip + i].run.count) << i;
    ASSERT_EQ(kept[i].run.direction, runs[skip + i].run.direction) << i;
  }
}

TEST(RecorderRotation, OneFilePerPrintAndNothingBetweenPrints) {
  ScratchDir dir("prints");
  auto opt = testing::test_options(dir.str());
  opt.config.keep_files = 2;
  auto rec = Recorder::create(opt);
  ASSERT_TRUE(rec.ok());
  Recorder& r = **rec;
  for (int p = 0; p < 4; ++p) {
    ASSERT_TRUE(r.start_print("print" + std::to_string(p)).ok());
    for (int i = 0; i <= p; ++i) r.writer(Stream::servo).encoder_sample(0, i, i);
    ASSERT_TRUE(r.end_print().ok());
    r.writer(Stream::servo).encoder_sample(0, 99, 99);  // between prints: discarded
    ASSERT_TRUE(r.poll().ok());
  }
  EXPECT_EQ(r.stats().records_discarded, 4u);
  const auto logs = dir.logs();
  ASSERT_EQ(logs.size(), 2u);  // keep_files
  for (size_t f = 0; f < logs.size(); ++f) {
    auto reader = LogReader::open(logs[f]);
    ASSERT_TRUE(reader.ok());
    EXPECT_EQ(reader->header().print_name, "print" + std::to_string(f + 2));
    size_t samples = 0;
    while (const DecodedRecord* d = reader->next()) samples += std::holds_alternative<EncoderRecord>(d->record);
    EXPECT_EQ(samples, f + 3);
  }
}

TEST(RecorderRotation, UnusableDirectoryIsAClearError) {
  auto opt = testing::test_options("/proc/feedloop-cannot-exist/x");
  auto rec = Recorder::create(opt);
  ASSERT_FALSE(rec.ok());
  EXPECT_NE(rec.error().message.find("cannot create directory"), std::string::npos) << rec.error().message;
  opt.config.directory = "${STATE_DIR}/recordings";
  auto rec2 = Recorder::create(opt);
  ASSERT_FALSE(rec2.ok());
  EXPECT_NE(rec2.error().message.find("not expanded"), std::string::npos);
}

}  // namespace
}  // namespace feedloop::recorder
