// "No allocation per line": after one warm-up pass, parsing a file's lines into a reused Command
// and running them through a HostProtocol with a reused Reply performs zero heap allocations.
// This binary replaces the global operator new to count calls.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>
#include <string>
#include <vector>

#include "gcode/file_lines.hpp"
#include "gcode/host_protocol.hpp"
#include "gcode/parser.hpp"

// The replacement operators pair malloc with free; GCC's heuristic cannot see that through
// inlining (false -Wmismatched-new-delete under the sanitizer build).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
#endif

namespace {
std::atomic<long> g_news{0};
}

void* operator new(std::size_t n) {
  g_news.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return operator new(n); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

namespace feedloop::gcode {
namespace {

std::vector<std::string> sample_lines() {
  std::vector<std::string> lines;
  for (const char* name : {"cube20_start.gcode", "dialect_mix.gcode"}) {
    const std::string path = std::string(FEEDLOOP_SOURCE_DIR) + "/tests/data/gcode/" + name;
    Status st = for_each_file_line(path, [&](const SplitLine& l) { lines.emplace_back(l.text); });
    EXPECT_TRUE(st.ok()) << path;
  }
  // Klipper's extended commands that slicers write (gcode/parser.cpp).
  for (const char* l :
       {"EXCLUDE_OBJECT_DEFINE NAME='Shape-Box id:0 copy 0' CENTER=110,110 "
        "POLYGON=[[100,100],[120,100],[120,120],[100,120]]",
        "EXCLUDE_OBJECT_START NAME='Shape-Box id:0 copy 0'", "EXCLUDE_OBJECT_END NAME=part_1",
        "EXCLUDE_OBJECT NAME=part_1", "SET_PRESSURE_ADVANCE ADVANCE=0.04 SMOOTH_TIME=0.03"})
    lines.emplace_back(l);
  return lines;
}

TEST(Allocation, ParsingReusedCommandAllocatesNothing) {
  const std::vector<std::string> lines = sample_lines();
  ASSERT_GT(lines.size(), 150u);
  Command cmd;
  const SourceLocation where{"a_long_source_name_beyond_sso.gcode", 1, 0};
  for (const auto& l : lines) ASSERT_TRUE(parse_line(l, where, cmd).ok()) << l;  // warm-up
  const long before = g_news.load();
  int commands = 0;
  for (const auto& l : lines) {
    if (parse_line(l, where, cmd).ok() && !cmd.empty()) ++commands;
  }
  EXPECT_EQ(g_news.load() - before, 0);
  EXPECT_GT(commands, 100);
}

TEST(Allocation, HostProtocolWithReusedReplyAllocatesNothing) {
  const std::vector<std::string> lines = sample_lines();
  HostProtocol p("a_long_channel_name_beyond_sso");
  Command cmd;
  Reply reply;
  reply.text.reserve(256);
  auto run = [&] {
    int executed = 0;
    for (const auto& l : lines) {
      reply.clear();
      if (p.on_line(l, reply, cmd) == HostProtocol::Action::kExecute) ++executed;
    }
    return executed;
  };
  run();
  const long before = g_news.load();
  const int executed = run();
  EXPECT_EQ(g_news.load() - before, 0);
  EXPECT_GT(executed, 100);
}

}  // namespace
}  // namespace feedloop::gcode
