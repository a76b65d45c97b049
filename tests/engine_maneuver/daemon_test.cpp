// The daemon accepts the DC-servo example config: `feedloopd --check-config --config
// config/examples/dc_servo_sim.yaml` exits 0, and a broken gain is reported with file:line:col.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

namespace {

// Runs `cmd`, returns its exit status and combined output.
int run(const std::string& cmd, std::string& out) {
  out.clear();
  FILE* p = popen((cmd + " 2>&1").c_str(), "r");
  if (p == nullptr) return -1;
  std::array<char, 512> buf{};
  while (fgets(buf.data(), static_cast<int>(buf.size()), p) != nullptr) out += buf.data();
  const int st = pclose(p);
  return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

const std::string kExample = FEEDLOOP_SOURCE_DIR "/config/examples/dc_servo_sim.yaml";

TEST(DcServoDaemon, CheckConfigAcceptsTheExample) {
  std::string out;
  const int rc = run(std::string(FEEDLOOPD_PATH) + " --check-config --config " + kExample, out);
  std::printf("%s", out.c_str());
  EXPECT_EQ(rc, 0) << out;
}

TEST(DcServoDaemon, CheckConfigReportsABadGainWithItsLocation) {
  std::ifstream in(kExample);
  std::ostringstream text;
  text << in.rdbuf();
  std::string yaml = text.str();
  const std::string from = "rate_hz: 5000";
  ASSERT_NE(yaml.find(from), std::string::npos);
  yaml.replace(yaml.find(from), from.size(), "rate_hz: 1000");
  int line = 1;
  const size_t kd = yaml.find("k_d_per_s: 1667");
  for (size_t i = 0; i < kd; ++i) line += yaml[i] == '\n';
  const size_t col = kd - yaml.rfind('\n', kd);
  const std::string path = std::string(FEEDLOOP_BINARY_DIR) + "/dc_servo_1khz.yaml";
  std::ofstream(path) << yaml;
  std::string out;
  const int rc = run(std::string(FEEDLOOPD_PATH) + " --check-config --config " + path, out);
  std::printf("%s", out.c_str());
  EXPECT_NE(rc, 0);
  const std::string at = "dc_servo_1khz.yaml:" + std::to_string(line) + ":" + std::to_string(col) + ":";
  EXPECT_NE(out.find(at), std::string::npos) << "expected " << at << " in\n" << out;
  EXPECT_NE(out.find("diverges above 1.5"), std::string::npos) << out;
}

}  // namespace
