// `feedloop print` against a running feedloopd (simulated printer in virtual time): the numbered
// and checksummed cube, the benchy and a file with M105 lines print to the end; errors are
// reported with the file's line numbers and counted as rejected; --resume-from.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "tests/daemon/daemon_fixture.hpp"
#include "tests/daemon/line_client.hpp"
#include "tests/daemon/subprocess.hpp"

namespace feedloop::testing {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// Command lines of a file as the client sends them (no comments, no blank lines, no M110).
int64_t command_lines(const std::string& path) {
  std::ifstream f(path);
  int64_t n = 0;
  for (std::string line; std::getline(f, line);) {
    line = line.substr(0, line.find(';'));
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    if (line.find("M110") != std::string::npos) continue;
    ++n;
  }
  return n;
}

struct Summary {
  int64_t sent = -1, acknowledged = -1, rejected = -1;
};

Summary parse_summary(const std::string& out) {
  Summary s;
  std::smatch m;
  if (std::regex_search(out, m, std::regex(R"(lines sent +(\d+) \((\d+) acknowledged, (\d+) rejected)"))) {
    s.sent = std::stoll(m[1]);
    s.acknowledged = std::stoll(m[2]);
    s.rejected = std::stoll(m[3]);
  }
  return s;
}

class PrintCommand : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = make_temp_dir("print");
    ASSERT_FALSE(dir_.empty());
    daemon_ = std::make_unique<Subprocess>(std::vector<std::string>{FEEDLOOPD_PATH, "--virtual-time"},
                                           env(), dir_ + "/daemon.log");
    ASSERT_TRUE(daemon_->wait_for_output("ready", 20)) << daemon_->output();
  }
  void TearDown() override {
    if (daemon_) {
      daemon_->signal(SIGTERM);
      EXPECT_EQ(daemon_->wait(10), 0);
    }
    daemon_.reset();
    fs::remove_all(dir_);
  }
  std::vector<std::string> env() { return {"RUNTIME_DIRECTORY=" + dir_, "STATE_DIRECTORY=" + dir_}; }
  // Runs `feedloop print FILE args...`; returns its exit code, its output in *out.
  int print(const std::string& file, std::string* out, std::vector<std::string> extra = {},
            double timeout_s = 600) {
    std::vector<std::string> argv{FEEDLOOP_PATH, "print", file};
    for (auto& a : extra) argv.push_back(a);
    Subprocess p(argv, env(), dir_ + "/print.log");
    const int rc = p.wait(timeout_s);
    *out = p.output();
    return rc;
  }
  json status() {
    LineClient c;
    if (!c.connect_unix(dir_ + "/api.sock", 100)) return json();
    c.send_line(R"({"jsonrpc":"2.0","id":1,"method":"status"})");
    auto line = c.read_line(5000);
    return line ? json::parse(*line)["result"] : json();
  }
  // The machine settles for a moment after M400 returns.
  bool wait_idle() {
    for (int i = 0; i < 200; ++i) {
      if (status()["state"] == "idle") return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return false;
  }
  std::string dir_;
  std::unique_ptr<Subprocess> daemon_;
};

std::string shared_gcode(const std::string& name) {
  return std::string(FEEDLOOP_SHARED_DIR) + "/gcode/" + name;
}

TEST_F(PrintCommand, PrintsTheNumberedAndChecksummedCubeToTheEnd) {
#ifdef FEEDLOOP_SANITIZED
  GTEST_SKIP() << "13 minutes of simulated motion: runs in the optimized build only";
#endif
  const std::string gcode = shared_gcode("cube20_cartesian_numbered_checksum.gcode");
  if (!fs::exists(gcode)) GTEST_SKIP() << "corpus " << gcode << " absent: test skipped";
  std::string out;
  const int rc = print(gcode, &out);
  const Summary s = parse_summary(out);
  const int64_t expected = command_lines(gcode);
  EXPECT_EQ(expected, 22187);  // 22,188 lines, the first the file's own M110
  EXPECT_EQ(rc, 0) << out.substr(0, 3000);
  EXPECT_EQ(s.sent, expected) << out.substr(0, 3000);
  EXPECT_EQ(s.acknowledged, expected);
  EXPECT_EQ(s.rejected, 0);
  EXPECT_NE(out.find("renumbered        22187 lines"), std::string::npos) << out.substr(0, 3000);
  EXPECT_TRUE(wait_idle());
  const json st = status();
  EXPECT_EQ(st["commands"]["rejected"], 0);
  EXPECT_GT(st["motion"]["print_time_s"].get<double>(), 600.0);
}

TEST_F(PrintCommand, PrintsTheBenchyToTheEnd) {
#ifdef FEEDLOOP_SANITIZED
  GTEST_SKIP() << "the whole benchy: runs in the optimized build only";
#endif
  const std::string gcode = shared_gcode("benchy_cartesian.gcode");
  if (!fs::exists(gcode)) GTEST_SKIP() << "corpus " << gcode << " absent: test skipped";
  std::string out;
  const int rc = print(gcode, &out);
  const Summary s = parse_summary(out);
  const int64_t expected = command_lines(gcode);
  EXPECT_GT(expected, 120000);  // 126,451 command lines
  EXPECT_EQ(rc, 0) << out.substr(0, 3000);
  EXPECT_EQ(s.sent, expected) << out.substr(0, 3000);
  EXPECT_EQ(s.acknowledged, expected);
  EXPECT_EQ(s.rejected, 0);
  EXPECT_TRUE(wait_idle());
  const json st = status();
  EXPECT_EQ(st["commands"]["rejected"], 0);
}

// The start of the cube with an M105 after every third command (Marlin answers "ok T:..."), one
// line that does not parse and one move outside the travel: both reported with their file line
// and counted as rejected; everything else runs.
TEST_F(PrintCommand, FileWithM105LinesAndErrorsPrintsToTheEndWithTheRightLineNumbers) {
  std::ifstream src(std::string(FEEDLOOP_SOURCE_DIR) + "/tests/data/gcode/cube20_start.gcode");
  ASSERT_TRUE(src);
  const std::string path = dir_ + "/m105.gcode";
  std::ofstream f(path);
  int line = 0, commands = 0, m105 = 0, parse_error_line = 0, travel_error_line = 0;
  for (std::string l; std::getline(src, l);) {
    f << l << "\n";
    ++line;
    if (l.substr(0, l.find(';')).find_first_not_of(" \t\r") == std::string::npos) continue;
    if (++commands % 3 == 0) {
      f << "M105\n";
      ++line;
      ++m105;
    }
    if (commands == 40) {
      f << "G1 X10 Q5 ; Q is not a G1 parameter\n";
      parse_error_line = ++line;
    }
    if (commands == 60) {
      f << "G1 X5000 F3000 ; outside the travel\n";
      travel_error_line = ++line;
    }
  }
  f << "M105\n";
  ++m105;
  f.close();
  std::string out;
  const int rc = print(path, &out, {}, 120);
  EXPECT_EQ(rc, 3) << out;  // some lines rejected
  const Summary s = parse_summary(out);
  EXPECT_EQ(s.sent, commands + m105 + 2) << out;
  EXPECT_EQ(s.acknowledged, s.sent) << out;
  EXPECT_EQ(s.rejected, 2) << out;
  EXPECT_GT(m105, 30);
  EXPECT_NE(out.find(path + ":" + std::to_string(parse_error_line) + ":"), std::string::npos)
      << "parse error not at line " << parse_error_line << ":\n" << out;
  EXPECT_NE(out.find(path + ":" + std::to_string(travel_error_line) + ":"), std::string::npos)
      << "travel error not at line " << travel_error_line << ":\n" << out;
  EXPECT_TRUE(wait_idle());
}

// --resume-from: the settings before the line are sent, the moves only followed; the head goes to
// where they left it and the print goes on from the line.
TEST_F(PrintCommand, ResumeFromALineRestoresSettingsAndPosition) {
  const std::string src = std::string(FEEDLOOP_SOURCE_DIR) + "/tests/data/gcode/cube20_start.gcode";
  std::ifstream in(src);
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  // Resume at the 3rd G1 with X after the purge line: the head must be where the line before
  // left it when the line starts, i.e. the full print and the resumed one end at the same place.
  int resume = 0, g1 = 0;
  for (size_t i = 0; i < lines.size(); ++i)
    if (lines[i].rfind("G1 X", 0) == 0 && ++g1 == 6) resume = static_cast<int>(i + 1);
  ASSERT_GT(resume, 30);
  std::string out;
  ASSERT_EQ(print(src, &out, {"--resume-from", std::to_string(resume)}, 120), 0) << out;
  const Summary s = parse_summary(out);
  EXPECT_EQ(s.rejected, 0);
  EXPECT_LT(s.sent, command_lines(src));
  EXPECT_NE(out.find("resumed from      line " + std::to_string(resume)), std::string::npos) << out;
  ASSERT_TRUE(wait_idle());
  const json resumed = status()["position_mm"];
  ASSERT_EQ(print(src, &out, {}, 120), 0) << out;
  ASSERT_TRUE(wait_idle());
  const json full = status()["position_mm"];
  for (const char* a : {"x", "y", "z", "e"}) EXPECT_NEAR(resumed[a].get<double>(), full[a].get<double>(), 1e-6) << a;
  // Bad arguments are refused with a message.
  EXPECT_EQ(print(src, &out, {"--resume-from", "0"}), 2);
  EXPECT_NE(out.find("--resume-from needs a positive whole number"), std::string::npos) << out;
  EXPECT_EQ(print(src, &out, {"--resume-from", "100000"}), 2);
  EXPECT_NE(out.find("past the end"), std::string::npos) << out;
}

}  // namespace
}  // namespace feedloop::testing
