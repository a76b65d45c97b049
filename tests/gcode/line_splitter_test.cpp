// LineSplitter: lines across chunk borders, CRLF and CR-only ends, the per-line cap, and bounded
// memory on megabyte lines.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "gcode/line_splitter.hpp"

namespace feedloop::gcode {
namespace {

struct Collected {
  std::vector<std::string> text;
  std::vector<int64_t> number;
  std::vector<size_t> length;
  std::vector<bool> too_long;
};

Collected split(const std::string& input, size_t chunk, size_t cap = 1024, bool cr = false,
                size_t* max_buffered = nullptr) {
  LineSplitter s(cap, cr);
  Collected c;
  auto sink = [&](const SplitLine& l) {
    c.text.emplace_back(l.text);
    c.number.push_back(l.number);
    c.length.push_back(l.length_bytes);
    c.too_long.push_back(l.too_long);
  };
  for (size_t i = 0; i < input.size(); i += chunk) {
    s.feed(std::string_view(input).substr(i, chunk), sink);
    if (max_buffered) *max_buffered = std::max(*max_buffered, s.buffered_bytes());
  }
  s.finish(sink);
  return c;
}

TEST(LineSplitter, SameLinesWhateverTheChunkSize) {
  const std::string input = "G1 X1\nG1 X2\r\n\n; comment\nM117 last";
  for (size_t chunk : {1u, 2u, 3u, 7u, 64u, 4096u}) {
    const Collected c = split(input, chunk);
    ASSERT_EQ(c.text.size(), 5u) << chunk;
    EXPECT_EQ(c.text[0], "G1 X1");
    EXPECT_EQ(c.text[1], "G1 X2");  // '\r' of "\r\n" dropped
    EXPECT_EQ(c.text[2], "");
    EXPECT_EQ(c.text[3], "; comment");
    EXPECT_EQ(c.text[4], "M117 last");  // no final newline: handed out by finish()
    EXPECT_EQ(c.number[4], 5);
  }
}

TEST(LineSplitter, CarriageReturnEndsLinesOnSerialChannels) {
  const std::string input = "M105\rM114\r\nM115\n\rG28\r";
  for (size_t chunk : {1u, 4u, 5u, 100u}) {
    const Collected c = split(input, chunk, 1024, /*cr=*/true);
    ASSERT_EQ(c.text.size(), 5u) << chunk;
    EXPECT_EQ(c.text[0], "M105");
    EXPECT_EQ(c.text[1], "M114");  // "\r\n" is one end
    EXPECT_EQ(c.text[2], "M115");
    EXPECT_EQ(c.text[3], "");      // "\n\r" is two ends
    EXPECT_EQ(c.text[4], "G28");
  }
}

TEST(LineSplitter, TooLongLineIsOneErrorAndTheRestIsDiscarded) {
  const std::string input = "G1 X1\n" + std::string(5000, 'A') + "\nG1 X2\n";
  for (size_t chunk : {1u, 100u, 999u, 1u << 16}) {
    size_t max_buffered = 0;
    const Collected c = split(input, chunk, 1000, false, &max_buffered);
    ASSERT_EQ(c.text.size(), 3u) << chunk;
    EXPECT_EQ(c.text[0], "G1 X1");
    EXPECT_TRUE(c.too_long[1]);
    EXPECT_EQ(c.length[1], 5000u);
    EXPECT_EQ(c.text[1], "");
    EXPECT_EQ(c.text[2], "G1 X2");
    EXPECT_EQ(c.number[2], 3);
    EXPECT_LE(max_buffered, 1000u) << chunk;
  }
  // Exactly at the cap is fine, one byte more is too long.
  const Collected at = split(std::string(1000, 'B') + "\n" + std::string(1001, 'C') + "\n", 300, 1000);
  ASSERT_EQ(at.text.size(), 2u);
  EXPECT_FALSE(at.too_long[0]);
  EXPECT_EQ(at.text[0].size(), 1000u);
  EXPECT_TRUE(at.too_long[1]);
}

TEST(LineSplitter, MegabyteLinesKeepMemoryBounded) {
  // 8 MB without a newline, then a normal line: the buffer never exceeds the default cap.
  LineSplitter s;
  const std::string block(1 << 20, 'x');
  size_t max_buffered = 0;
  int lines = 0;
  bool saw_too_long = false;
  auto sink = [&](const SplitLine& l) {
    ++lines;
    if (l.too_long) {
      saw_too_long = true;
      EXPECT_EQ(l.length_bytes, 8u << 20);
    } else {
      EXPECT_EQ(l.text, "M400");
    }
  };
  for (int i = 0; i < 8; ++i) {
    s.feed(block, sink);
    max_buffered = std::max(max_buffered, s.buffered_bytes());
  }
  s.feed("\nM400\n", sink);
  s.finish(sink);
  EXPECT_TRUE(saw_too_long);
  EXPECT_EQ(lines, 2);
  EXPECT_LE(max_buffered, LineSplitter::kDefaultMaxLineBytes);
  EXPECT_EQ(s.buffered_bytes(), 0u);
}

TEST(LineSplitter, TooLongLastLineWithoutNewlineIsReportedByFinish) {
  const Collected c = split("G28\n" + std::string(3000, 'Z'), 512, 1000);
  ASSERT_EQ(c.text.size(), 2u);
  EXPECT_EQ(c.text[0], "G28");
  EXPECT_TRUE(c.too_long[1]);
  EXPECT_EQ(c.length[1], 3000u);
  EXPECT_EQ(c.number[1], 2);
}

}  // namespace
}  // namespace feedloop::gcode
