// Print jobs through feedloopd (docs/jobs.md): files uploaded over the JSON API and printed from
// the job folder by the daemon itself, Marlin's SD commands on the socket, pause/resume in the
// middle of the benchy and cancel. The machine runs in virtual time (feedloopd --virtual-time),
// the channels on the wall clock. Built twice: daemon_jobs_test (the short cube) and, with
// FEEDLOOP_JOBS_BENCHY, daemon_jobs_benchy_test (label long: half the benchy).
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "daemon_fixture.hpp"
#include "gcode/parser.hpp"
#include "tests/daemon/json_call.hpp"
#include "tests/daemon/line_client.hpp"

namespace feedloop::testing {
namespace {

using nlohmann::json;

[[maybe_unused]] std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

[[maybe_unused]] std::string base64(const std::string& in) {
  static const char* t = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  uint32_t acc = 0;
  int bits = 0;
  for (unsigned char c : in) {
    acc = (acc << 8) | c;
    bits += 8;
    while (bits >= 6) {
      bits -= 6;
      out.push_back(t[(acc >> bits) & 63]);
    }
  }
  if (bits > 0) out.push_back(t[(acc << (6 - bits)) & 63]);
  while (out.size() % 4) out.push_back('=');
  return out;
}

[[maybe_unused]] size_t command_lines(const std::string& text) {
  size_t n = 0;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) {
    auto c = gcode::parse_line(l, SourceLocation{"t", 1, 0});
    if (c && !c->empty()) ++n;
  }
  return n;
}

// Polls job.status until `pred` holds (or the timeout): the last status.
template <class Pred>
json wait_job(LineClient& api, Pred pred, int timeout_s) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(timeout_s);
  json j;
  while (std::chrono::steady_clock::now() < deadline) {
    j = call(api, "job.status")["result"];
    if (j.is_object() && pred(j)) return j;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return j;
}

class Jobs : public DaemonFixture {
 protected:
  bool virtual_time() const override { return true; }
  void customize(config::MachineConfig& cfg) override {
    cfg.jobs.directory = dir_ + "/gcodes";
    cfg.recorder.enabled = false;
  }
};

#ifndef FEEDLOOP_JOBS_BENCHY
TEST_F(Jobs, AFileFromTheFolderRunsStartToEndThroughTheDaemon) {
  const std::string text =
      read_file(std::string(FEEDLOOP_SOURCE_DIR) + "/examples/gcode/cube20_3layers.gcode");
  ASSERT_GT(text.size(), 1000u);
  LineClient api;
  ASSERT_TRUE(api.connect_unix(daemon_->api_socket_path()));
  // Upload (base64) and bad uploads.
  json up =
      call(api, "files.upload", {{"filename", "cube.gcode"}, {"content_base64", base64(text)}});
  ASSERT_TRUE(up.contains("result")) << up.dump();
  EXPECT_EQ(up["result"]["size"], text.size());
  json esc = call(api, "files.upload", {{"filename", "../cube.gcode"}, {"content", "G28\n"}});
  ASSERT_TRUE(esc.contains("error")) << esc.dump();
  EXPECT_NE(esc["error"]["message"].get<std::string>().find("path separator at byte 3"),
            std::string::npos);
  json bad64 = call(api, "files.upload", {{"filename", "x.gcode"}, {"content_base64", "AB$D"}});
  EXPECT_EQ(bad64["error"]["code"], -32602) << bad64.dump();
  json list = call(api, "files.list");
  ASSERT_EQ(list["result"]["files"].size(), 1u) << list.dump();
  EXPECT_EQ(list["result"]["files"][0]["filename"], "cube.gcode");
  EXPECT_FALSE(std::filesystem::exists(dir_ + "/cube.gcode"));
  // Another client owns the print: the job may not start.
  LineClient other;
  ASSERT_TRUE(other.connect_unix(daemon_->socket_path()));
  ASSERT_TRUE(other.send_line("G28"));
  ASSERT_TRUE(other.read_until("ok", 10000));
  json busy = call(api, "job.start", {{"filename", "cube.gcode"}});
  ASSERT_TRUE(busy.contains("error")) << busy.dump();
  EXPECT_NE(busy["error"]["message"].get<std::string>().find("busy"), std::string::npos);
  other.close();
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // its ownership ends with it

  const json before = call(api, "status")["result"];
  json started = call(api, "job.start", {{"filename", "cube.gcode"}});
  ASSERT_TRUE(started.contains("result")) << started.dump();
  EXPECT_EQ(started["result"]["state"], "printing");
  api.close();  // the job is the daemon's: it goes on without the client that started it

  LineClient marlin;
  ASSERT_TRUE(marlin.connect_unix(daemon_->socket_path()));
  ASSERT_TRUE(marlin.send_line("M27"));
  auto m27 = marlin.read_line(5000);
  ASSERT_TRUE(m27);
  EXPECT_EQ(m27->rfind("SD printing byte ", 0), 0u) << *m27;
  EXPECT_NE(m27->find("/" + std::to_string(text.size())), std::string::npos) << *m27;
  ASSERT_TRUE(marlin.read_until("ok"));
  ASSERT_TRUE(marlin.send_line("G1 X1"));  // the job owns the print
  auto refused = marlin.read_until("Error:", 5000);
  ASSERT_TRUE(refused);
  EXPECT_NE(refused->find("owned by the print job 'cube.gcode'"), std::string::npos) << *refused;
  // M27 S1: Marlin's auto-report of the job's progress every second (of the machine's time).
  ASSERT_TRUE(marlin.send_line("M27 S1"));
  ASSERT_TRUE(marlin.read_until("ok"));
  uint64_t last_byte = 0;
  for (int k = 0; k < 2; ++k) {
    auto report = marlin.read_until("SD printing byte ", 10000);
    ASSERT_TRUE(report) << "auto-report " << k;
    const uint64_t byte = std::stoull(report->substr(report->rfind(' ') + 1));
    EXPECT_GE(byte, last_byte);
    last_byte = byte;
  }
  ASSERT_TRUE(marlin.send_line("M27 S0"));
  ASSERT_TRUE(marlin.read_until("ok"));

  LineClient api2;
  ASSERT_TRUE(api2.connect_unix(daemon_->api_socket_path()));
  const json done = wait_job(
      api2, [](const json& j) { return j["state"] != "printing"; }, 300);
  ASSERT_EQ(done["state"], "complete") << done.dump();
  const json after = call(api2, "status")["result"];
  const size_t lines = command_lines(text);
  EXPECT_EQ(done["lines_submitted"], lines);
  EXPECT_EQ(done["position_bytes"], text.size());
  EXPECT_DOUBLE_EQ(done["progress"]["bytes"].get<double>(), 1.0);
  EXPECT_DOUBLE_EQ(done["estimated_remaining_s"].get<double>(), 0.0);
  const uint64_t executed = after["commands"]["executed"].get<uint64_t>() -
                            before["commands"]["executed"].get<uint64_t>();
  EXPECT_EQ(executed, lines);
  EXPECT_EQ(after["commands"]["rejected"], before["commands"]["rejected"]);
  EXPECT_EQ(after["motion"]["lost_step_events"], 0);
  EXPECT_GT(done["print_time_s"].get<double>(), 10.0);
  std::printf("cube: %zu commands, print time %.1f s, elapsed %.1f s wall\n", lines,
              done["print_time_s"].get<double>(), done["elapsed_s"].get<double>());
  ASSERT_TRUE(marlin.send_line("M27"));
  auto idle = marlin.read_until("Not SD printing", 5000);
  EXPECT_TRUE(idle);
}
// An M112 in a job's file stops the machine when the job reaches it (Marlin's M112 from the SD
// card kills the printer); the job ends in error at that line and the move after it never runs.
// It was taken for a no-op: the job ran on to its end.
// A job started right after a console move, the move still in the lookahead, heats and runs:
// the heater wait (M190, M109) releases the lookahead first. Before, in virtual time, the wait
// waited for the move and the move for the wait's end (no time passed: stuck at M190 for good).
TEST_F(Jobs, AJobStartedRightAfterAMoveHeatsAndRuns) {
  LineClient api;
  ASSERT_TRUE(api.connect_unix(daemon_->api_socket_path()));
  const std::string text =
      read_file(std::string(FEEDLOOP_SOURCE_DIR) + "/examples/gcode/cube20_3layers.gcode");
  ASSERT_NE(text.find("M190 S60"), std::string::npos);
  ASSERT_TRUE(call(api, "files.upload", {{"filename", "cube.gcode"}, {"content", text}})
                  .contains("result"));
  const json moved = call(api, "gcode", {{"script", "G28\nG1 X12 Y7 F3000"}});
  ASSERT_TRUE(moved.contains("result")) << moved.dump();
  ASSERT_TRUE(call(api, "job.start", {{"filename", "cube.gcode"}}).contains("result"));
  const json done = wait_job(
      api, [](const json& j) { return j["state"] != "printing"; }, 60);
  EXPECT_EQ(done["state"], "complete") << done.dump();
  EXPECT_GT(done["print_time_s"].get<double>(), 10.0) << done.dump();
}

TEST_F(Jobs, AnM112InTheFileStopsTheMachine) {
  LineClient api;
  ASSERT_TRUE(api.connect_unix(daemon_->api_socket_path()));
  const std::string text = "G28\nG1 X20 F6000\nM112\nG1 X50 F6000\n";
  ASSERT_TRUE(call(api, "files.upload", {{"filename", "stop.gcode"}, {"content", text}})
                  .contains("result"));
  ASSERT_TRUE(call(api, "job.start", {{"filename", "stop.gcode"}}).contains("result"));
  const json done = wait_job(
      api, [](const json& j) { return j["state"] != "printing"; }, 60);
  EXPECT_EQ(done["state"], "error") << done.dump();
  EXPECT_NE(done.dump().find("stop.gcode:3"), std::string::npos) << done.dump();
  const json st = call(api, "status")["result"];
  EXPECT_EQ(st["state"], "emergency_stopped") << st.dump();
  EXPECT_LT(st["position_mm"]["x"].get<double>(), 20.0 + 1e-9);
}

#else
TEST_F(Jobs, PauseResumeInTheMiddleOfTheBenchyAndCancel) {
  const std::string src = std::string(FEEDLOOP_SHARED_DIR) + "/gcode/benchy_cartesian.gcode";
  if (!std::filesystem::exists(src)) GTEST_SKIP() << "the public G-code corpus is not at " << src;
  // The benchy with an M25 at the line boundary after its middle byte: the job pauses itself there
  // (Marlin's M25 in an SD print), so the pause point does not depend on this test's timing.
  std::string text = read_file(src);
  const size_t middle = text.find('\n', text.size() / 2) + 1;
  text.insert(middle, "M25 ; pause in the middle (test)\n");
  {
    std::ofstream out(dir_ + "/gcodes/benchy_cartesian.gcode", std::ios::binary);
    out << text;
  }
  const uint64_t size = text.size();

  LineClient marlin;
  ASSERT_TRUE(marlin.connect_unix(daemon_->socket_path()));
  ASSERT_TRUE(marlin.send_line("M21"));
  EXPECT_TRUE(marlin.read_until("echo:SD card ok"));
  ASSERT_TRUE(marlin.read_until("ok"));
  ASSERT_TRUE(marlin.send_line("M20"));
  ASSERT_TRUE(marlin.read_until("Begin file list"));
  auto entry = marlin.read_line();
  ASSERT_TRUE(entry);
  EXPECT_EQ(*entry, "benchy_cartesian.gcode " + std::to_string(size));
  ASSERT_TRUE(marlin.read_until("End file list"));
  ASSERT_TRUE(marlin.read_until("ok"));
  ASSERT_TRUE(marlin.send_line("M23 benchy_cartesian.gcode"));
  auto opened = marlin.read_until("File opened:");
  ASSERT_TRUE(opened);
  EXPECT_EQ(*opened, "File opened: benchy_cartesian.gcode Size: " + std::to_string(size));
  ASSERT_TRUE(marlin.read_until("File selected"));
  ASSERT_TRUE(marlin.read_until("ok"));
  ASSERT_TRUE(marlin.send_line("M24"));
  ASSERT_TRUE(marlin.read_until("ok"));
  marlin.close();  // started from the socket; the print does not depend on it

  LineClient api;
  ASSERT_TRUE(api.connect_unix(daemon_->api_socket_path()));
  const json mid = wait_job(
      api, [&](const json& j) { return j["state"] != "printing"; }, 1200);
  ASSERT_TRUE(mid["state"] == "pausing" || mid["state"] == "paused") << mid.dump();
  EXPECT_EQ(mid["position_bytes"].get<uint64_t>(), middle + 33);  // the M25 line: the pause point
  std::printf(
      "middle: byte %llu of %llu, print time %.1f s, estimated total %.1f s, remaining %.1f s, "
      "elapsed %.1f s\n",
      static_cast<unsigned long long>(mid["position_bytes"].get<uint64_t>()),
      static_cast<unsigned long long>(size), mid["print_time_s"].get<double>(),
      mid["estimated_total_s"].get<double>(), mid["estimated_remaining_s"].get<double>(),
      mid["elapsed_s"].get<double>());
  const json before_pause = call(api, "status")["result"];
  const double hotend_target = before_pause["temperatures_c"]["hotend_target"].get<double>();
  const double bed_target = before_pause["temperatures_c"]["bed_target"].get<double>();
  ASSERT_GT(hotend_target, 150.0);
  ASSERT_GT(bed_target, 40.0);
  json paused = call(api, "job.pause");  // pausing already: a no-op, as Marlin's M25 twice
  ASSERT_TRUE(paused.contains("result")) << paused.dump();
  const json p = wait_job(
      api, [](const json& j) { return j["state"] != "pausing"; }, 120);
  ASSERT_EQ(p["state"], "paused") << p.dump();
  const json ps = call(api, "status")["result"];
  // Heaters held; the head parked (X min + 10, Y max - 10 of the embedded config), Z raised.
  EXPECT_DOUBLE_EQ(ps["temperatures_c"]["hotend_target"].get<double>(), hotend_target);
  EXPECT_DOUBLE_EQ(ps["temperatures_c"]["bed_target"].get<double>(), bed_target);
  const json& pp = p["pause_position"];
  ASSERT_TRUE(pp.is_object()) << p.dump();
  EXPECT_NEAR(ps["position_mm"]["z"].get<double>(), pp["pos_mm"][2].get<double>() + 5.0, 1e-6);
  std::printf("paused at X%.4f Y%.4f Z%.4f E%.4f, parked at X%.3f Y%.3f Z%.3f\n",
              pp["pos_mm"][0].get<double>(), pp["pos_mm"][1].get<double>(),
              pp["pos_mm"][2].get<double>(), pp["pos_mm"][3].get<double>(),
              ps["position_mm"]["x"].get<double>(), ps["position_mm"]["y"].get<double>(),
              ps["position_mm"]["z"].get<double>());

  json resumed = call(api, "job.resume");
  ASSERT_TRUE(resumed.contains("result")) << resumed.dump();
  const json r = wait_job(
      api, [](const json& j) { return j["state"] != "resuming"; }, 120);
  ASSERT_EQ(r["state"], "printing") << r.dump();
  const json& rp = r["resume_position"];
  ASSERT_TRUE(rp.is_object()) << r.dump();
  // Back at the same place: the same step on X Y Z; the encoders (0.49 um per count) against their
  // reading at the pause.
  const double count_mm = 0.49e-3;
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(rp["pos_mm"][i].get<double>(), pp["pos_mm"][i].get<double>(), 1e-9) << "axis " << i;
    EXPECT_EQ(rp["step_count"][i].get<int64_t>(), pp["step_count"][i].get<int64_t>())
        << "axis " << i;
  }
  EXPECT_NEAR(rp["pos_mm"][3].get<double>(), pp["pos_mm"][3].get<double>(), 1e-9);
  for (int i = 0; i < 2; ++i) {
    ASSERT_TRUE(rp["encoder_mm"][i].is_number() && pp["encoder_mm"][i].is_number()) << r.dump();
    const double d = rp["encoder_mm"][i].get<double>() - pp["encoder_mm"][i].get<double>();
    std::printf(
        "axis %c: encoder at pause %.6f mm, after resume %.6f mm, difference %.3f um (%.2f "
        "counts)\n",
        "XY"[i], pp["encoder_mm"][i].get<double>(), rp["encoder_mm"][i].get<double>(), d * 1e3,
        std::fabs(d) / count_mm);
    // Issue 16: one encoder count. In whole steps it was 3-5 (X) and 8 (Y) counts here (the rest
    // point within a 10.6 um step depends on the arrival); with the device loop's sub-step trim
    // 1-2 on Y (a 25 Hz limit cycle of +-2.6 counts, and a G4 that took no time); with the
    // trim's proportional band and the G4 a real dwell: X 0, Y 1 (docs/jobs.md).
    EXPECT_LE(std::fabs(d), count_mm * (1.0 + 1e-6)) << "axis " << i;
  }
  // Let it print on a little, then cancel: every heater off, parked.
  const uint64_t lines = r["lines_submitted"].get<uint64_t>();
  const json on = wait_job(
      api, [&](const json& j) { return j["lines_submitted"].get<uint64_t>() > lines + 300; }, 300);
  ASSERT_EQ(on["state"], "printing");
  json cancelled = call(api, "job.cancel");
  ASSERT_TRUE(cancelled.contains("result")) << cancelled.dump();
  const json c = wait_job(
      api, [](const json& j) { return j["state"] != "cancelling"; }, 120);
  ASSERT_EQ(c["state"], "cancelled") << c.dump();
  json s;
  for (int i = 0; i < 50; ++i) {
    s = call(api, "status")["result"];
    if (s["temperatures_c"]["hotend_target"] == 0.0 && s["temperatures_c"]["bed_target"] == 0.0 &&
        s["state"] == "idle")
      break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  EXPECT_DOUBLE_EQ(s["temperatures_c"]["hotend_target"].get<double>(), 0.0);
  EXPECT_DOUBLE_EQ(s["temperatures_c"]["bed_target"].get<double>(), 0.0);
  EXPECT_EQ(s["motion"]["lost_step_events"], 0);
  EXPECT_EQ(s["commands"]["rejected"], 0);
  EXPECT_EQ(s["job"]["state"], "cancelled");
  // The machine is free again for any client.
  LineClient after;
  ASSERT_TRUE(after.connect_unix(daemon_->socket_path()));
  ASSERT_TRUE(after.send_line("G1 X100 Y100 F6000"));
  auto ok = after.read_line(10000);
  ASSERT_TRUE(ok);
  EXPECT_EQ(*ok, "ok");
}
#endif

}  // namespace
}  // namespace feedloop::testing
