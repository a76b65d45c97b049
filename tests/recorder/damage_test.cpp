// A truncated or damaged log gives a clear error with the byte offset, and the reader still
// returns every record before the damage.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>

#include "recorder/log_reader.hpp"
#include "recorder/log_summary.hpp"
#include "recorder/recorder.hpp"
#include "recorder/step_stream.hpp"
#include "recorder_test_util.hpp"

namespace feedloop::recorder {
namespace {

using testing::ScratchDir;

std::vector<uint8_t> read_bytes(const std::string& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}
void write_bytes(const std::string& p, const std::vector<uint8_t>& b) {
  std::ofstream f(p, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
}

struct ReadBack {
  std::vector<DecodedRecord> records;
  std::optional<Error> error;
  uint64_t blocks = 0;
};
ReadBack read_back(const std::string& path) {
  ReadBack rb;
  auto r = LogReader::open(path);
  EXPECT_TRUE(r.ok()) << (r.ok() ? "" : r.error().to_string());
  if (!r.ok()) return rb;
  while (const DecodedRecord* d = r->next()) rb.records.push_back(*d);
  rb.error = r->error();
  rb.blocks = r->blocks();
  return rb;
}

// A log of ~40 blocks: encoder samples with a counter we can check.
std::string make_log(const ScratchDir& dir) {
  auto opt = testing::test_options(dir.str());
  opt.block_bytes = 256;
  auto rec = Recorder::create(opt);
  EXPECT_TRUE(rec.ok());
  EXPECT_TRUE((*rec)->start_print("damage").ok());
  for (int i = 0; i < 3000; ++i) {
    (*rec)->writer(Stream::servo).encoder_sample(i % 4, 1000 * i, i);
    if (i % 50 == 49) {
      EXPECT_TRUE((*rec)->poll().ok());
    }
  }
  EXPECT_TRUE((*rec)->end_print().ok());
  return dir.logs().at(0);
}

bool same_prefix(const std::vector<DecodedRecord>& part, const std::vector<DecodedRecord>& full) {
  if (part.size() > full.size()) return false;
  for (size_t i = 0; i < part.size(); ++i)
    if (part[i].offset != full[i].offset || part[i].record.index() != full[i].record.index()) return false;
  return true;
}

TEST(RecorderDamage, TruncatedFileReturnsEverythingBeforeTheCut) {
  ScratchDir dir("trunc");
  const std::string path = make_log(dir);
  const ReadBack full = read_back(path);
  ASSERT_FALSE(full.error.has_value());
  ASSERT_GT(full.blocks, 20u);
  const auto bytes = read_bytes(path);
  const size_t cut = bytes.size() * 3 / 5;
  write_bytes(path, std::vector<uint8_t>(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(cut)));

  const ReadBack part = read_back(path);
  ASSERT_TRUE(part.error.has_value());
  const std::string msg = part.error->to_string();
  EXPECT_NE(msg.find("truncated block"), std::string::npos) << msg;
  EXPECT_NE(msg.find("at byte offset "), std::string::npos) << msg;
  // Every intact block before the cut is returned: records up to the cut, in order.
  ASSERT_GT(part.records.size(), full.records.size() / 2);
  EXPECT_TRUE(same_prefix(part.records, full.records));
  EXPECT_LT(part.records.back().offset, cut);
  // The offset named is the start of the first block that is not complete: past the last record
  // returned, before the cut.
  const size_t at = msg.find("at byte offset ") + 15;
  const uint64_t offset = std::stoull(msg.substr(at));
  EXPECT_GT(offset, part.records.back().offset);
  EXPECT_LT(offset, cut);
  // The summary still works and reports the damage.
  auto sum = summarize_log(path);
  ASSERT_TRUE(sum.ok());
  EXPECT_EQ(sum->records, part.records.size());
  EXPECT_NE(format_summary(*sum).find("DAMAGED"), std::string::npos);
}

TEST(RecorderDamage, FlippedByteFailsTheBlockCrcAtItsOffset) {
  ScratchDir dir("flip");
  const std::string path = make_log(dir);
  const ReadBack full = read_back(path);
  auto bytes = read_bytes(path);
  // Damage a byte inside the body of a record in the middle of the file.
  const DecodedRecord& victim = full.records[full.records.size() / 2];
  bytes[victim.offset] ^= 0x5A;
  write_bytes(path, bytes);

  const ReadBack part = read_back(path);
  ASSERT_TRUE(part.error.has_value());
  const std::string msg = part.error->message;
  EXPECT_NE(msg.find("fails its CRC check"), std::string::npos) << msg;
  EXPECT_TRUE(same_prefix(part.records, full.records));
  // The records returned are exactly those of the blocks before the damaged one.
  ASSERT_FALSE(part.records.empty());
  EXPECT_LT(part.records.back().offset, victim.offset);
  const size_t first_lost = part.records.size();
  EXPECT_GE(full.records[first_lost].offset, part.records.back().offset);
  EXPECT_LE(full.records[first_lost].offset, victim.offset);
  const uint64_t block_offset = std::stoull(msg.substr(msg.find("at byte offset ") + 15));
  EXPECT_GT(block_offset, part.records.back().offset);
  EXPECT_LT(block_offset, victim.offset);
}

TEST(RecorderDamage, BadMarkerBetweenBlocks) {
  ScratchDir dir("marker");
  const std::string path = make_log(dir);
  auto bytes = read_bytes(path);
  // The first block starts right after the header: 16 fixed bytes, the body, its CRC.
  const size_t body = bytes[12] | (bytes[13] << 8) | (bytes[14] << 16) | (static_cast<size_t>(bytes[15]) << 24);
  const size_t marker = 16 + body + 4;
  ASSERT_EQ(bytes[marker], 0xB7);
  ASSERT_GT(marker, 16u);
  bytes[marker] = 0x00;
  write_bytes(path, bytes);
  const ReadBack part = read_back(path);
  ASSERT_TRUE(part.error.has_value());
  EXPECT_EQ(part.records.size(), 0u);
  EXPECT_NE(part.error->message.find("bad block marker 0x00 at byte offset " + std::to_string(marker)), std::string::npos)
      << part.error->message;
}

TEST(RecorderDamage, NotALogAndTruncatedHeaderFailToOpen) {
  ScratchDir dir("header");
  const std::string path = make_log(dir);
  auto bytes = read_bytes(path);

  write_bytes(dir.file("short.flrec"), std::vector<uint8_t>(bytes.begin(), bytes.begin() + 30));
  auto a = LogReader::open(dir.file("short.flrec"));
  ASSERT_FALSE(a.ok());
  EXPECT_NE(a.error().message.find("truncated file header at byte offset 30"), std::string::npos) << a.error().message;

  write_bytes(dir.file("text.flrec"), std::vector<uint8_t>{'G', '1', ' ', 'X', '1', '0', '\n', 'G', '1', ' ', 'Y', '1', '0', '\n', 'M', '8', '4'});
  auto b = LogReader::open(dir.file("text.flrec"));
  ASSERT_FALSE(b.ok());
  EXPECT_NE(b.error().message.find("bad magic at byte offset 0"), std::string::npos);
  EXPECT_EQ(b.error().where.source, dir.file("text.flrec"));

  auto c = LogReader::open(dir.file("missing.flrec"));
  ASSERT_FALSE(c.ok());
  EXPECT_NE(c.error().message.find("cannot open"), std::string::npos);

  bytes[20] ^= 1;  // inside the header body
  write_bytes(dir.file("hdr.flrec"), bytes);
  auto d = LogReader::open(dir.file("hdr.flrec"));
  ASSERT_FALSE(d.ok());
  EXPECT_NE(d.error().message.find("file header CRC mismatch"), std::string::npos);

  // A read error is not a short file (a directory reads with EISDIR; it was "truncated file
  // header at byte offset 0").
  auto e = LogReader::open(dir.file(""));
  ASSERT_FALSE(e.ok());
  EXPECT_NE(e.error().message.find("cannot read log: Is a directory"), std::string::npos)
      << e.error().message;
}

// A step run that breaks the step law (found by fuzz/fuzz_recording_reader.cpp: a run of
// 4016029694 steps made the summary's step-clock arithmetic overflow; the reproducer is
// fuzz/corpus/recording/regress_step_run_overflow). The format keeps any run bit for bit, so the
// reader returns it; the summary counts it without computing its clocks, and the step streams a
// replay compares refuse it with its offset.
TEST(RecorderDamage, StepRunsThatBreakTheStepLawAreCountedButNotExpanded) {
  ScratchDir dir("steplaw");
  auto rec = Recorder::create(testing::test_options(dir.str()));
  ASSERT_TRUE(rec.ok());
  ASSERT_TRUE((*rec)->start_print("steplaw").ok());
  RecordWriter& w = (*rec)->writer(Stream::servo);
  w.step_run(0, 1000, stepgen::StepRun{500, -2, 100, 1});  // clocks 1500 .. 41100
  w.step_run(0, 60000, stepgen::StepRun{300, 0, 10, -1});  // .. 63000
  w.step_run(0, 70000, stepgen::StepRun{3, -1, 5, 1});     // intervals 3, 2, 1, 0, -1
  w.step_run(0, 80000, stepgen::StepRun{int64_t{1} << 40, 0, 4'000'000'000u, 1});  // beyond 2^63
  ASSERT_TRUE((*rec)->end_print().ok());
  const std::string path = dir.logs().at(0);

  const ReadBack rb = read_back(path);
  EXPECT_FALSE(rb.error.has_value());
  auto sum = summarize_log(path);
  ASSERT_TRUE(sum.ok());
  const JointSummary& j = sum->joints.at(0);
  EXPECT_EQ(j.step_runs, 4u);
  EXPECT_EQ(j.invalid_runs, 2u);
  EXPECT_EQ(j.first_clock, 1500);
  EXPECT_EQ(j.last_clock, 63000);
  EXPECT_NE(format_summary(*sum).find("2 runs breaking the step law"), std::string::npos)
      << format_summary(*sum);

  auto streams = read_step_streams({path});
  ASSERT_FALSE(streams.ok());
  EXPECT_NE(streams.error().message.find("breaks the step law"), std::string::npos)
      << streams.error().message;
  EXPECT_NE(streams.error().message.find("at byte offset "), std::string::npos);
}

// Random damage anywhere (a flipped byte or a cut): never a crash, always either a clean read or
// an error naming a byte offset, and what was returned is a prefix of the intact log.
TEST(RecorderDamage, RandomDamageNeverCrashes) {
  ScratchDir dir("random");
  const std::string path = make_log(dir);
  const ReadBack full = read_back(path);
  const auto bytes = read_bytes(path);
  std::mt19937 rng(99);
  int errors = 0;
  for (int trial = 0; trial < 300; ++trial) {
    auto damaged = bytes;
    const size_t at = rng() % bytes.size();
    if (trial % 2) damaged[at] ^= static_cast<uint8_t>(1 + rng() % 255);
    else damaged.resize(at);
    write_bytes(path, damaged);
    auto r = LogReader::open(path);
    if (!r.ok()) {
      EXPECT_LT(at, 16u + 1000u) << "only header damage may fail open(): " << r.error().message;
      continue;
    }
    std::vector<DecodedRecord> got;
    while (const DecodedRecord* d = r->next()) got.push_back(*d);
    if (r->error()) {
      ++errors;
      EXPECT_NE(r->error()->message.find("byte offset"), std::string::npos) << r->error()->message;
      EXPECT_TRUE(same_prefix(got, full.records));
    }
  }
  EXPECT_GT(errors, 200);
}

}  // namespace
}  // namespace feedloop::recorder
