// Virtual time does not depend on the host's pace (docs/calibration.md, "Deterministic under
// load"): a program sent right after the previous one's M400 and the same program sent after a
// wall-clock pause run the same motion. Before, M400 returned at the plan's end while the loop's
// hold ran on at CPU speed, so the next program's G4 met the hold (and became motion) or did not,
// as the host's pace chose.
#include <gtest/gtest.h>

#include <chrono>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "daemon_fixture.hpp"
#include "line_client.hpp"

namespace feedloop::testing {
namespace {

using nlohmann::json;

class VirtualTime : public DaemonFixture {
 protected:
  bool virtual_time() const override { return true; }
  void customize(config::MachineConfig& cfg) override {
    cfg.control.mode = config::ControlMode::pi;  // the loop holds the position after each plan
    cfg.recorder.enabled = false;
  }
  void restart() {
    TearDown();
    SetUp();
  }

  json status() {
    LineClient api;
    EXPECT_TRUE(api.connect_unix(daemon_->api_socket_path()));
    EXPECT_TRUE(api.send_line(R"({"jsonrpc":"2.0","id":1,"method":"status"})"));
    auto line = api.read_line(10000);
    return line ? json::parse(*line, nullptr, false)["result"] : json();
  }

  // The lines at once, then one ok per line.
  static void send_all(LineClient& c, const std::vector<std::string>& lines) {
    std::string text;
    for (const std::string& l : lines) text += l + "\n";
    ASSERT_TRUE(c.send(text));
    for (const std::string& l : lines) ASSERT_TRUE(c.read_until("ok", 30000)) << l;
  }

  struct Figures {
    double samples = 0.0, e_t_mm = 0.0;
  };
  // Program A, a wall-clock pause, program B: B's tracking error samples and mean.
  Figures a_pause_b(int pause_ms) {
    LineClient c;
    EXPECT_TRUE(c.connect_unix(daemon_->socket_path()));
    send_all(c, {"G90", "G1 X100 Y100 F6000", "G1 X130 Y110 F9000", "M400"});
    std::this_thread::sleep_for(std::chrono::milliseconds(pause_ms));
    const json a = status()["motion"]["tracking_error_mm"];
    send_all(c, {"G4 P300", "G1 X100 Y120 F9000", "G1 X110 Y100 F9000", "M400"});
    const json b = status()["motion"]["tracking_error_mm"];
    Figures f;
    const double na = a.value("samples", 0.0), nb = b.value("samples", 0.0);
    f.samples = nb - na;
    f.e_t_mm = f.samples > 0.0 ? (b.value("mean", 0.0) * nb - a.value("mean", 0.0) * na) / f.samples : 0.0;
    return f;
  }
};

TEST_F(VirtualTime, TheNextProgramRunsTheSameWhateverTheHostsPause) {
  const Figures now = a_pause_b(0);
  restart();
  const Figures later = a_pause_b(500);
  std::printf("program B right after A's M400: %.0f samples, e_t %.6f mm; 500 ms later: %.0f, %.6f mm\n",
              now.samples, now.e_t_mm, later.samples, later.e_t_mm);
  EXPECT_GT(now.samples, 100.0);  // B ran closed loop and was measured
  EXPECT_EQ(now.samples, later.samples);
  EXPECT_DOUBLE_EQ(now.e_t_mm, later.e_t_mm);
}

}  // namespace
}  // namespace feedloop::testing
