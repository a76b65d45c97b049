// Real files: the repo's own samples (always) and the shared slicer corpus (skipped visibly when
// ../shared is absent): zero parse errors, line and move counts that match the corpus README,
// and the numbered/checksummed file through the host protocol, intact and corrupted.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "gcode/file_lines.hpp"
#include "gcode/host_protocol.hpp"
#include "gcode/parser.hpp"

namespace fs = std::filesystem;

namespace feedloop::gcode {
namespace {

const fs::path kShared = fs::path(FEEDLOOP_SHARED_DIR) / "gcode";
const fs::path kRepoSamples = fs::path(FEEDLOOP_SOURCE_DIR) / "tests" / "data" / "gcode";

struct FileStats {
  int64_t lines = 0;
  int64_t commands = 0;
  int64_t moves = 0;  // G0 + G1
  int64_t unknown = 0;
  std::vector<std::string> errors;
};

FileStats parse_file(const fs::path& path) {
  FileStats s;
  Command cmd;
  SourceLocation where{path.filename().string(), 0, 0};
  Status st = for_each_file_line(path.string(), [&](const SplitLine& line) {
    ++s.lines;
    where.line = static_cast<int>(line.number);
    if (line.too_long) {
      s.errors.push_back(where.to_string() + ": line too long");
      return;
    }
    Status ps = parse_line(line.text, where, cmd);
    if (!ps) {
      if (s.errors.size() < 5) s.errors.push_back(ps.error().to_string());
      return;
    }
    if (cmd.empty()) return;
    ++s.commands;
    if (cmd.unknown) ++s.unknown;
    if (cmd.is('G', 0) || cmd.is('G', 1)) ++s.moves;
  });
  EXPECT_TRUE(st.ok()) << path;
  return s;
}

std::vector<fs::path> files_in(const fs::path& dir) {
  std::vector<fs::path> out;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec))
    if (e.path().extension() == ".gcode") out.push_back(e.path());
  std::sort(out.begin(), out.end());
  return out;
}

TEST(Corpus, RepoSamplesParseWithoutErrors) {
  const auto files = files_in(kRepoSamples);
  ASSERT_GE(files.size(), 2u) << kRepoSamples;
  for (const auto& f : files) {
    const FileStats s = parse_file(f);
    EXPECT_TRUE(s.errors.empty()) << f << ": " << (s.errors.empty() ? "" : s.errors[0]);
    EXPECT_GT(s.commands, 40) << f;
    EXPECT_EQ(s.unknown, 0) << f;  // the samples use only validated codes
  }
}

TEST(Corpus, MissingFileIsAnErrorNamingIt) {
  int lines = 0;
  Status st = for_each_file_line("no/such/file.gcode", [&](const SplitLine&) { ++lines; });
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.error().where.source, "no/such/file.gcode");
  EXPECT_NE(st.error().message.find("cannot open"), std::string::npos);
  EXPECT_EQ(lines, 0);
}

// A compressed file, an archive or PrusaSlicer's binary G-code is refused before any line, with
// what it is; the same bytes after a text line are lines like any (only the head is sniffed).
TEST(Corpus, CompressedArchivedAndBinaryGcodeAreRefusedWhole) {
  const fs::path dir = fs::temp_directory_path() / ("feedloop-kind-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  struct Case {
    std::string bytes, fragment;
  };
  const Case cases[] = {
      {std::string("GCDE\x01\0\0\0\x01\0", 10) + "G1 X1\n",
       "binary G-code (PrusaSlicer's .bgcode)"},
      {std::string("\x1f\x8b\x08\0\0\0\0\0", 8) + "\nG1 X1\n", "gzip-compressed"},
      {std::string("\xfd"
                   "7zXZ\0\0\x04",
                   8) +
           "\nG1 X1\n",
       "xz-compressed"},
      {std::string("PK\x03\x04\x14\0\0\0", 8) + "\nG1 X1\n", "ZIP archive (a .3mf project?)"},
  };
  for (const Case& c : cases) {
    const fs::path f = dir / "f.gcode";
    std::ofstream(f, std::ios::binary) << c.bytes;
    int lines = 0;
    const Status st = for_each_file_line(f.string(), [&](const SplitLine&) { ++lines; });
    ASSERT_FALSE(st.ok()) << c.fragment;
    EXPECT_EQ(st.error().where.source, f.string());
    EXPECT_EQ(st.error().message.rfind("not G-code: ", 0), 0u) << st.error().message;
    EXPECT_NE(st.error().message.find(c.fragment), std::string::npos) << st.error().message;
    EXPECT_EQ(lines, 0) << c.fragment;
  }
  const fs::path text = dir / "t.gcode";
  std::ofstream(text, std::ios::binary) << "G28\nGCDE\nPK\n";
  int lines = 0;
  EXPECT_TRUE(for_each_file_line(text.string(), [&](const SplitLine&) { ++lines; }).ok());
  EXPECT_EQ(lines, 3);
  fs::remove_all(dir);
}

TEST(Corpus, SharedFilesParseWithoutErrors) {
  const auto files = files_in(kShared);
  if (files.empty()) GTEST_SKIP() << "shared G-code corpus not found at " << kShared << " (skipped)";
  // Physical lines and G0/G1 counts from the corpus README (made by its own tools/gcode_stats.py).
  const std::map<std::string, std::pair<int64_t, int64_t>> expected = {
      {"benchy_cartesian.gcode", {151609, 118208}},
      {"benchy_delta.gcode", {151612, 118219}},
      {"cube20_cartesian.gcode", {23479, 21136}},
      {"cube20_cartesian_numbered_checksum.gcode", {22188, 21136}},
      {"vase_cylinder_cartesian.gcode", {77336, 73899}},
      {"star_prism_cartesian.gcode", {99055, 95055}},
      {"circles_plate_cartesian.gcode", {159142, 128378}},
  };
  for (const auto& f : files) {
    const FileStats s = parse_file(f);
    EXPECT_TRUE(s.errors.empty()) << f << ": " << (s.errors.empty() ? "" : s.errors[0]);
    const auto it = expected.find(f.filename().string());
    if (it != expected.end()) {
      EXPECT_EQ(s.lines, it->second.first) << f;
      EXPECT_EQ(s.moves, it->second.second) << f;
    }
  }
}

std::vector<std::string> read_lines(const fs::path& path) {
  std::vector<std::string> lines;
  Status st = for_each_file_line(path.string(),
                                 [&](const SplitLine& l) { lines.emplace_back(l.text); });
  EXPECT_TRUE(st.ok());
  return lines;
}

// A host that streams `lines`, honours "Resend: n" by going back to line n (line n is at index n:
// the file starts with N0), and damages some lines on their first transmission only.
struct HostRun {
  std::vector<int64_t> resends;
  std::vector<int64_t> executed;  // line numbers of the executed commands, in order
  int64_t oks = 0;
  int64_t sent = 0;
};

HostRun stream(const std::vector<std::string>& lines, const std::map<size_t, std::string>& damage,
               const std::set<size_t>& drop) {
  HostProtocol p("pty");
  HostRun run;
  std::set<size_t> used_damage;
  Reply r;
  Command cmd;
  for (size_t i = 0; i < lines.size();) {
    if (drop.count(i) && !used_damage.count(i)) {  // lost on the wire once
      used_damage.insert(i);
      ++i;
      continue;
    }
    std::string line = lines[i];
    if (damage.count(i) && !used_damage.count(i)) {
      used_damage.insert(i);
      line = damage.at(i);
    }
    r.clear();
    ++run.sent;
    if (p.on_line(line, r, cmd) == HostProtocol::Action::kExecute) run.executed.push_back(cmd.line_number);
    for (size_t pos = 0; (pos = r.text.find("ok\n", pos)) != std::string::npos; pos += 3) ++run.oks;
    const size_t rs = r.text.find("Resend: ");
    if (rs != std::string::npos) {
      const int64_t n = std::stoll(r.text.substr(rs + 8));
      run.resends.push_back(n);
      i = static_cast<size_t>(n);
    } else {
      ++i;
    }
    if (run.sent > static_cast<int64_t>(lines.size()) * 2) break;  // no livelock
  }
  return run;
}

TEST(Corpus, NumberedChecksummedFileThroughTheHostProtocol) {
  const fs::path f = kShared / "cube20_cartesian_numbered_checksum.gcode";
  if (!fs::exists(f)) GTEST_SKIP() << f << " not found (shared corpus absent; skipped)";
  const std::vector<std::string> lines = read_lines(f);
  ASSERT_EQ(lines.size(), 22188u);

  const HostRun clean = stream(lines, {}, {});
  EXPECT_TRUE(clean.resends.empty());
  EXPECT_EQ(clean.oks, static_cast<int64_t>(lines.size()));  // every line accepted
  ASSERT_EQ(clean.executed.size(), lines.size() - 1);       // all but the leading M110
  for (size_t k = 0; k < clean.executed.size(); ++k) ASSERT_EQ(clean.executed[k], static_cast<int64_t>(k + 1));

  // Corrupted copy: a flipped bit in line 500's payload, a wrong checksum on line 7000, line 12345
  // lost on the wire, and line 20000 without its checksum.
  std::map<size_t, std::string> damage;
  std::string l500 = lines[500];
  l500[l500.find(' ') + 2] ^= 0x01;
  damage[500] = l500;
  std::string l7000 = lines[7000];
  l7000.back() = l7000.back() == '9' ? '8' : '9';
  damage[7000] = l7000;
  damage[20000] = lines[20000].substr(0, lines[20000].rfind('*'));
  const HostRun bad = stream(lines, damage, {12345});
  EXPECT_EQ(bad.resends, (std::vector<int64_t>{500, 7000, 12345, 20000}));
  // Nothing lost, nothing doubled: each command executed exactly once, in order.
  ASSERT_EQ(bad.executed.size(), clean.executed.size());
  EXPECT_EQ(bad.executed, clean.executed);
  // One ok per line the protocol received (the dropped line never arrived).
  EXPECT_EQ(bad.oks, bad.sent);
}

}  // namespace
}  // namespace feedloop::gcode
