// End-to-end tests of feedloopd's client channels against a running daemon: the Unix socket and
// the pty with the Marlin host protocol, the JSON API, print ownership, slow clients, shutdown.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <filesystem>
#include <vector>

#include "tests/daemon/daemon_fixture.hpp"
#include "tests/daemon/json_call.hpp"
#include "tests/daemon/line_client.hpp"

namespace feedloop::testing {
namespace {

using nlohmann::json;

class Channels : public DaemonFixture {
 protected:
  // Heaters that heat in about a second (the keepalive test needs waits of known length): small
  // heat capacities, short lags, no derivative braking, no residency.
  void customize(config::MachineConfig& cfg) override {
    for (config::HeaterConfig& h : cfg.heaters) {
      h.plant.heat_capacity_j_k = h.kind == config::HeaterKind::bed ? 10.0 : 1.0;
      h.plant.delay_s = 0.05;
      h.plant.sensor_tau_s = 0.1;
      h.pid_kd = 0.0;
      h.residency_s = 0.0;
    }
  }
};

TEST_F(Channels, UnixSocketSpeaksTheMarlinHostProtocol) {
  LineClient c;
  ASSERT_TRUE(c.connect_unix(daemon_->socket_path()));
  ASSERT_TRUE(c.send_line("M115"));
  auto fw = c.read_line();
  ASSERT_TRUE(fw);
  EXPECT_NE(fw->find("FIRMWARE_NAME:feedloop"), std::string::npos);
  EXPECT_EQ(c.read_line(), "ok");

  ASSERT_TRUE(c.send_line(numbered(0, "M110 N0")));
  EXPECT_EQ(c.read_line(), "ok");
  ASSERT_TRUE(c.send_line(numbered(1, "G1 X12.5 Y3 F3000")));
  EXPECT_EQ(c.read_line(), "ok");
  // A corrupted checksum: the line is refused and resent, nothing moves.
  std::string bad = numbered(2, "G1 X99");
  bad.back() = bad.back() == '0' ? '1' : '0';
  ASSERT_TRUE(c.send_line(bad));
  EXPECT_EQ(c.read_line(), "Error:checksum mismatch, Last Line: 1");
  EXPECT_EQ(c.read_line(), "Resend: 2");
  EXPECT_EQ(c.read_line(), "ok");
  // A skipped line number.
  ASSERT_TRUE(c.send_line(numbered(3, "G1 X98")));
  EXPECT_EQ(c.read_line(), "Error:Line Number is not Last Line Number+1, Last Line: 1");
  EXPECT_EQ(c.read_line(), "Resend: 2");
  EXPECT_EQ(c.read_line(), "ok");
  ASSERT_TRUE(c.send_line(numbered(2, "G1 Z0.3")));
  EXPECT_EQ(c.read_line(), "ok");
  ASSERT_TRUE(c.send_line("M114"));
  auto pos = c.read_line();
  ASSERT_TRUE(pos);
  EXPECT_EQ(pos->rfind("X:12.50 Y:3.00 Z:0.30", 0), 0u) << *pos;
  EXPECT_EQ(c.read_line(), "ok");
  // A line that fails validation: an error with its location, and nothing executes.
  ASSERT_TRUE(c.send_line("G1 X5 Q7"));
  auto err = c.read_line();
  ASSERT_TRUE(err);
  EXPECT_EQ(err->rfind("Error:", 0), 0u);
  EXPECT_NE(err->find("socket#1:8:7:"), std::string::npos) << *err;  // 8th line, column 7
  EXPECT_EQ(c.read_line(), "ok");
  ASSERT_TRUE(c.send_line("M114"));
  pos = c.read_line();
  ASSERT_TRUE(pos);
  EXPECT_EQ(pos->rfind("X:12.50 ", 0), 0u) << *pos;
}

// Per-link telemetry: every MCU of the simulated printer, with its frames, round trips and clock
// rate (the virtual MCUs run 50 ppm fast or slow, alternately: engine/mcu_bridge.hpp).
TEST_F(Channels, StatusShowsEveryMcuLink) {
  LineClient printer;
  ASSERT_TRUE(printer.connect_unix(daemon_->socket_path()));
  ASSERT_TRUE(printer.send_line("G1 X5 Y5 F6000"));
  ASSERT_TRUE(printer.read_until("ok", 5000));
  ASSERT_TRUE(printer.send_line("M400"));
  ASSERT_TRUE(printer.read_until("ok", 10000));
  LineClient api;
  ASSERT_TRUE(api.connect_unix(daemon_->api_socket_path()));
  const json st = call(api, {{"jsonrpc", "2.0"}, {"id", 1}, {"method", "status"}});
  const json& links = st["result"]["links"];
  ASSERT_EQ(links.size(), 4u) << st.dump();  // mcu_x, mcu_y, mcu_z, mcu_e
  for (size_t i = 0; i < links.size(); ++i) {
    const json& l = links[i];
    std::printf("%s\n", l.dump().c_str());
    SCOPED_TRACE(l.dump());
    EXPECT_EQ(l["state"], "ready");
    EXPECT_GT(l["frames_sent"].get<uint64_t>(), 10u);  // identify, configure, clock queries, steps
    EXPECT_GT(l["delivered"].get<uint64_t>(), 10u);
    EXPECT_EQ(l["crc_errors"].get<uint64_t>(), 0u);
    EXPECT_GT(l["clock_samples"].get<int>(), 8);
    const double rtt_min = l["rtt_us"]["min"].get<double>(),
                 rtt_mean = l["rtt_us"]["mean"].get<double>();
    EXPECT_GT(rtt_min, 0.0);
    EXPECT_LE(rtt_min, rtt_mean);
    EXPECT_LT(rtt_mean, 5000.0);
    const double expected_ppm = i % 2 == 0 ? 50.0 : -50.0;
    EXPECT_NEAR(l["clock_rate_ppm"].get<double>(), expected_ppm, 1.0);  // measured within 0.002 ppm
    // The simulated links have no I/O thread: nothing refused, nothing lost, the fit inline.
    EXPECT_EQ(l["io"]["tx_queue_full"].get<uint64_t>(), 0u);
    EXPECT_EQ(l["io"]["errors"].get<uint64_t>(), 0u);
    EXPECT_EQ(l["io"]["clock_fit"], "inline");
  }
  EXPECT_EQ(links[0]["name"], "mcu_x");
}

TEST_F(Channels, PtyLooksLikeAMarlinSerialPort) {
  LineClient tty;
  ASSERT_TRUE(tty.open_tty(daemon_->pty_link())) << daemon_->pty_link();
  ASSERT_TRUE(tty.send_line(numbered(0, "M110 N0")));
  EXPECT_EQ(tty.read_line(), "ok");
  ASSERT_TRUE(tty.send_line(numbered(1, "G1 X4 Y4 F6000")));
  EXPECT_EQ(tty.read_line(), "ok");
  ASSERT_TRUE(tty.send_line("M105"));
  auto t = tty.read_line();
  ASSERT_TRUE(t);
  EXPECT_EQ(t->rfind("ok T:", 0), 0u) << *t;
  // Closing and reopening the port keeps the daemon serving it.
  tty.close();
  LineClient again;
  ASSERT_TRUE(again.open_tty(daemon_->pty_link()));
  ASSERT_TRUE(again.send_line("M114"));
  auto pos = again.read_until("X:");
  ASSERT_TRUE(pos);
  EXPECT_EQ(pos->rfind("X:4.00 Y:4.00", 0), 0u) << *pos;
}

// A host that leaves the port as a terminal's defaults (echo on) must not make the pty send the
// daemon's replies back to it as commands: before the fix one M105 became an endless exchange of
// errors ("parameter O before any command", 330 kB in 3 s). One question, one answer, and the
// port's echo is off again.
TEST_F(Channels, PtyWithATerminalsEchoOnAnswersOnce) {
  LineClient tty;
  ASSERT_TRUE(tty.open_tty(daemon_->pty_link())) << daemon_->pty_link();
  ASSERT_TRUE(tty.set_terminal_defaults());
  ASSERT_TRUE(tty.echoes());
  ASSERT_TRUE(tty.send_line("M105"));
  auto t = tty.read_line();
  ASSERT_TRUE(t);
  EXPECT_EQ(t->rfind("ok T:", 0), 0u) << *t;
  std::vector<std::string> more;
  while (more.size() < 100)
    if (auto extra = tty.read_line(1000))
      more.push_back(*extra);
    else
      break;
  EXPECT_TRUE(more.empty()) << more.size() << " more lines, the first: " << more.front();
  EXPECT_FALSE(tty.echoes());
  // The port still serves: the next question gets its one answer.
  ASSERT_TRUE(tty.send_line("M114"));
  auto pos = tty.read_until("X:");
  ASSERT_TRUE(pos);
  EXPECT_EQ(pos->rfind("X:0.00", 0), 0u) << *pos;
}

// config.reload: as SIGHUP, and {open_loop: true} rebuilds the machine open loop until the next
// reload without it (feedloop calibrate's excitation); a wrong parameter is refused, nothing done.
TEST_F(Channels, ConfigReloadRebuildsTheMachineOpenLoopOnRequest) {
  LineClient api;
  ASSERT_TRUE(api.connect_unix(daemon_->api_socket_path()));
  auto info = [&] {
    return call(api, {{"jsonrpc", "2.0"}, {"id", 1}, {"method", "info"}})["result"];
  };
  auto reloads = [&] {
    return call(api,
                {{"jsonrpc", "2.0"}, {"id", 2}, {"method", "status"}})["result"]["config_reloads"]
        .get<uint64_t>();
  };
  EXPECT_EQ(info()["control"], "pi");
  json bad = call(api, {{"jsonrpc", "2.0"},
                        {"id", 3},
                        {"method", "config.reload"},
                        {"params", {{"open_loop", "yes"}}}});
  ASSERT_TRUE(bad.contains("error")) << bad.dump();
  json bad2 = call(api, {{"jsonrpc", "2.0"},
                         {"id", 3},
                         {"method", "config.reload"},
                         {"params", {{"no_feedforward", 1}}}});
  ASSERT_TRUE(bad2.contains("error")) << bad2.dump();
  EXPECT_EQ(bad2["error"]["message"], "'no_feedforward' must be true or false");
  EXPECT_EQ(bad["error"]["code"], -32602);
  EXPECT_EQ(bad["error"]["message"], "'open_loop' must be true or false");
  const uint64_t before = reloads();
  for (const bool open_loop : {true, false}) {
    json r = call(api, {{"jsonrpc", "2.0"},
                        {"id", 4},
                        {"method", "config.reload"},
                        {"params", {{"open_loop", open_loop}}}});
    ASSERT_TRUE(r.contains("result")) << r.dump();
    EXPECT_EQ(r["result"]["open_loop"], open_loop);
    const uint64_t want = before + (open_loop ? 1 : 2);
    for (int i = 0; i < 500 && reloads() < want; ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    EXPECT_EQ(reloads(), want);
    EXPECT_EQ(info()["control"], open_loop ? "open_loop" : "pi");
    EXPECT_EQ(info()["open_loop_override"], open_loop);
  }
}

TEST_F(Channels, JsonApiAnswersStatusRunsGcodeAndStreamsSubscriptions) {
  LineClient api;
  ASSERT_TRUE(api.connect_unix(daemon_->api_socket_path()));
  json info = call(api, {{"jsonrpc", "2.0"}, {"id", 1}, {"method", "info"}});
  EXPECT_EQ(info["result"]["kinematics"], "cartesian");
  EXPECT_TRUE(info["result"]["simulated"].get<bool>());

  json run = call(api, {{"jsonrpc", "2.0"},
                        {"id", 2},
                        {"method", "gcode"},
                        {"params", {{"script", "G91\nG1 X7 Y2\nG1 X1\nM114"}}}});
  ASSERT_TRUE(run.contains("result")) << run.dump();
  ASSERT_EQ(run["result"]["results"].size(), 4u);
  EXPECT_EQ(run["result"]["results"][3]["reply"].get<std::string>().rfind("X:8.00 Y:2.00", 0), 0u);

  json st = call(api, {{"jsonrpc", "2.0"}, {"id", 3}, {"method", "status"}});
  EXPECT_DOUBLE_EQ(st["result"]["position_mm"]["x"].get<double>(), 8.0);
  EXPECT_EQ(st["result"]["state"], "busy");  // the moves take real time on the machine
  for (int i = 0; i < 500 && st["result"]["state"] != "idle"; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    st = call(api, {{"jsonrpc", "2.0"}, {"id", 3}, {"method", "status"}});
  }
  EXPECT_EQ(st["result"]["state"], "idle");
  for (int i = 0; i < 200 && st["result"]["servo"]["cycles"].get<uint64_t>() < 10; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));  // the servo loop is running
    st = call(api, {{"jsonrpc", "2.0"}, {"id", 3}, {"method", "status"}});
  }
  EXPECT_GE(st["result"]["servo"]["cycles"].get<uint64_t>(), 10u);

  json bad_line = call(api, {{"jsonrpc", "2.0"},
                             {"id", 4},
                             {"method", "gcode"},
                             {"params", {{"script", "G1 X1\nG1 X2 W3\nG1 X50"}}}});
  const json& results = bad_line["result"]["results"];
  ASSERT_EQ(results.size(), 2u) << bad_line.dump();  // stops at the failing line
  EXPECT_FALSE(results[1]["ok"].get<bool>());
  EXPECT_NE(results[1]["error"].get<std::string>().find(":2:"), std::string::npos);

  EXPECT_EQ(call(api, {{"jsonrpc", "2.0"}, {"id", 5}, {"method", "nope"}})["error"]["code"],
            -32601);
  ASSERT_TRUE(api.send_line("{\"jsonrpc\": \"2.0\", \"id\": 6, \"method\": }"));
  json perr = json::parse(*api.read_line());
  EXPECT_EQ(perr["error"]["code"], -32700);
  EXPECT_NE(perr["error"]["message"].get<std::string>().find("column 39: syntax error"),
            std::string::npos)
      << perr.dump();

  json sub = call(api, {{"jsonrpc", "2.0"},
                        {"id", 7},
                        {"method", "subscribe"},
                        {"params", {{"topics", {"status"}}, {"interval_ms", 20}}}});
  EXPECT_TRUE(sub["result"]["status"].get<bool>());
  int notifications = 0;
  const auto t0 = std::chrono::steady_clock::now();
  while (notifications < 5 && std::chrono::steady_clock::now() - t0 < std::chrono::seconds(5)) {
    auto line = api.read_line(1000);
    ASSERT_TRUE(line);
    json n = json::parse(*line);
    if (n.value("method", "") == "status") {
      EXPECT_TRUE(n["params"].contains("position_mm"));
      ++notifications;
    }
  }
  EXPECT_EQ(notifications, 5);
  const double elapsed_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_GT(elapsed_s, 0.06);  // paced by the interval, not a flood
}

// The three one-line crashes of issue 14, replayed while a print runs: each got std::terminate
// before (dump() of a non-UTF-8 string, the parse of invalid UTF-8, the parse of 1e400). Now each
// gets an error answer; the connection, the other client and the print go on. Virtual time, so
// the check is about input and not about the machine's load (issue 13).
class HostileInput : public DaemonFixture {
  bool virtual_time() const override { return true; }
};

TEST_F(HostileInput, HostileLinesGetAnErrorAndThePrintGoesOn) {
  LineClient printer, api;
  ASSERT_TRUE(printer.connect_unix(daemon_->socket_path()));
  ASSERT_TRUE(api.connect_unix(daemon_->api_socket_path()));
  // A print in progress: 40 short moves, about 5 s of motion.
  for (int i = 0; i < 40; ++i) {
    ASSERT_TRUE(printer.send_line("G1 X" + std::to_string(10 + (i % 2) * 10) + " Y" +
                                  std::to_string(10 + i / 2) + " F6000"));
    ASSERT_EQ(printer.read_line(5000), "ok");
  }
  // 1. M117 with bytes that are not UTF-8 (Latin-1 "été", then a lone 0xFF), then a status request.
  ASSERT_TRUE(printer.send_line("M117 \xE9t\xE9 \xFF"));
  EXPECT_EQ(printer.read_line(), "ok");
  json st = call(api, {{"jsonrpc", "2.0"}, {"id", 1}, {"method", "status"}});
  ASSERT_TRUE(st.contains("result")) << st.dump();
  EXPECT_EQ(st["result"]["message"], "\xEF\xBF\xBDt\xEF\xBF\xBD \xEF\xBF\xBD");
  EXPECT_EQ(st["result"]["state"], "busy");  // still printing
  // 2. A JSON-RPC message with invalid UTF-8 inside a string.
  ASSERT_TRUE(api.send_line("{\"jsonrpc\":\"2.0\",\"id\":2,\"method\":\"st\xC3\x28tus\"}"));
  auto line = api.read_line();
  ASSERT_TRUE(line);
  json r = json::parse(*line);
  EXPECT_EQ(r["error"]["code"], -32700);
  EXPECT_NE(r["error"]["message"].get<std::string>().find("column 37"), std::string::npos) << *line;
  EXPECT_NE(r["error"]["message"].get<std::string>().find("not valid UTF-8"), std::string::npos);
  // 3. An id out of the range of every number type.
  ASSERT_TRUE(api.send_line("{\"jsonrpc\":\"2.0\",\"id\":1e400,\"method\":\"status\"}"));
  line = api.read_line();
  ASSERT_TRUE(line);
  r = json::parse(*line);
  EXPECT_EQ(r["error"]["code"], -32700);
  EXPECT_TRUE(r["id"].is_null());
  // Other out-of-range numbers and a G-code error that quotes non-UTF-8 bytes.
  ASSERT_TRUE(
      api.send_line("{\"jsonrpc\":\"2.0\",\"id\":3,\"method\":\"subscribe\","
                    "\"params\":{\"topics\":[\"status\"],\"interval_ms\":1e300}}"));
  r = json::parse(*api.read_line());
  EXPECT_EQ(r["result"]["interval_ms"], 60000);
  r = call(api, {{"jsonrpc", "2.0"},
                 {"id", 4},
                 {"method", "unsubscribe"},
                 {"params", {{"topics", {"status"}}}}});
  EXPECT_TRUE(r.contains("result"));
  ASSERT_TRUE(
      api.send_line("{\"jsonrpc\":\"2.0\",\"id\":5,\"method\":\"gcode\","
                    "\"params\":{\"script\":\"G1 X1 \\u00e9\"}}"));
  r = json::parse(*api.read_line());
  EXPECT_TRUE(r.contains("error") || r.contains("result")) << r.dump();
  ASSERT_TRUE(printer.send_line("G1 X5 \xFE"));  // an invalid word: an error with its column
  auto err = printer.read_line();
  ASSERT_TRUE(err);
  EXPECT_EQ(err->rfind("Error:", 0), 0u) << *err;
  EXPECT_EQ(printer.read_line(), "ok");
  st = call(api, {{"jsonrpc", "2.0"}, {"id", 6}, {"method", "status"}});
  ASSERT_TRUE(st.contains("result")) << st.dump();
  // The print goes on to its end where the moves put it, with no fault.
  for (int i = 0; i < 3000 && st["result"]["state"] != "idle"; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    st = call(api, {{"jsonrpc", "2.0"}, {"id", 7}, {"method", "status"}});
  }
  EXPECT_EQ(st["result"]["state"], "idle") << st.dump();
  EXPECT_EQ(st["result"]["commands"]["executed"], 40) << st.dump();  // every move, nothing lost
  EXPECT_DOUBLE_EQ(st["result"]["position_mm"]["x"].get<double>(), 20.0);
  EXPECT_DOUBLE_EQ(st["result"]["position_mm"]["y"].get<double>(), 29.0);
  EXPECT_EQ(st["result"]["last_error"], "");
  ASSERT_TRUE(printer.send_line("M114"));
  EXPECT_EQ(printer.read_line()->rfind("X:20.00 Y:29.00 ", 0), 0u);
}

TEST_F(Channels, OneClientOwnsThePrintAtATime) {
  LineClient a, b;
  ASSERT_TRUE(a.connect_unix(daemon_->socket_path()));
  ASSERT_TRUE(b.connect_unix(daemon_->socket_path()));
  ASSERT_TRUE(a.send_line("G1 X1"));
  EXPECT_EQ(a.read_line(), "ok");
  ASSERT_TRUE(b.send_line("G1 X2"));
  auto busy = b.read_line();
  ASSERT_TRUE(busy);
  EXPECT_EQ(busy->rfind("Error:busy: the print is owned by", 0), 0u) << *busy;
  EXPECT_EQ(b.read_line(), "ok");
  ASSERT_TRUE(b.send_line("M105"));  // queries are answered for everyone
  EXPECT_EQ(b.read_line()->rfind("ok T:", 0), 0u);
  a.close();  // the owner leaves: ownership is released
  std::optional<std::string> reply;
  for (int i = 0; i < 50; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    ASSERT_TRUE(b.send_line("G1 X2"));
    reply = b.read_line();
    if (reply == "ok") break;
    b.read_line();  // the ok after the busy error
  }
  EXPECT_EQ(reply, "ok");
  ASSERT_TRUE(b.send_line("M114"));
  EXPECT_EQ(b.read_line()->rfind("X:2.00 ", 0), 0u);
}

// Marlin's keepalive: "echo:busy: processing" every 2 s of a blocking command, counted from the
// moment the host started waiting. A wait as the connection's first command once got "busy" at
// the first 5 ms tick (the count started at 0 when no tick had seen the client idle yet).
TEST_F(Channels, KeepalivesCountTwoSecondsFromTheStartOfAWait) {
  LineClient c;
  ASSERT_TRUE(c.connect_unix(daemon_->socket_path()));
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(c.send_line("M190 S41"));  // 22 -> 40 C at 25 C/s: a wait of about a second
  EXPECT_EQ(c.read_line(5000), "ok");
  EXPECT_GT(std::chrono::steady_clock::now() - t0, std::chrono::milliseconds(300));
  ASSERT_TRUE(c.send_line("M109 S141"));  // 22 -> 140 C at 40 C/s: a 3 s wait, one keepalive
  EXPECT_EQ(c.read_line(5000), "echo:busy: processing");
  EXPECT_EQ(c.read_line(5000), "ok");
}

TEST_F(Channels, AClientThatNeverReadsDoesNotStallMotion) {
  LineClient sleeper;  // subscribes to fast status notifications and never reads them
  ASSERT_TRUE(sleeper.connect_unix(daemon_->api_socket_path()));
  ASSERT_TRUE(sleeper.send_line(
      R"({"jsonrpc":"2.0","id":1,"method":"subscribe","params":{"topics":["status"],"interval_ms":20}})"));
  LineClient printer;
  ASSERT_TRUE(printer.connect_unix(daemon_->socket_path()));
  const auto t0 = std::chrono::steady_clock::now();
  constexpr int kMoves = 300;  // 0.5 mm zig-zag at 100 mm/s: a few seconds of real motion
  for (int i = 1; i <= kMoves; ++i) {
    ASSERT_TRUE(printer.send_line("G1 X" + std::to_string(10 + (i % 2) * 0.5) + " Y" +
                                  std::to_string(10 + i * 0.01) + " F6000"));
    std::string skipped;  // "echo:busy: processing" keepalives while the machine catches up
    ASSERT_TRUE(printer.read_until("ok", 10000, &skipped)) << "at line " << i;
    EXPECT_TRUE(skipped.empty() || skipped.rfind("echo:busy", 0) == 0) << skipped;
  }
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(30));
  LineClient api;
  ASSERT_TRUE(api.connect_unix(daemon_->api_socket_path()));
  json st = call(api, {{"jsonrpc", "2.0"}, {"id", 2}, {"method", "status"}});
  EXPECT_EQ(st["result"]["commands"]["executed"].get<uint64_t>(), static_cast<uint64_t>(kMoves));
}

TEST_F(Channels, OverlongLinesAreRejectedWithoutGrowingMemory) {
  LineClient c;
  ASSERT_TRUE(c.connect_unix(daemon_->socket_path()));
  std::string huge(3 * 1024 * 1024, 'X');
  std::thread writer([&] { c.send("G1 " + huge + "\nG1 X3\n"); });
  auto err = c.read_line(10000);
  writer.join();
  ASSERT_TRUE(err);
  EXPECT_EQ(err->rfind("Error:", 0), 0u) << *err;
  EXPECT_EQ(c.read_line(), "ok");
  EXPECT_EQ(c.read_line(), "ok");  // G1 X3 still runs
  ASSERT_TRUE(c.send_line("M114"));
  EXPECT_EQ(c.read_line()->rfind("X:3.00 ", 0), 0u);
}

TEST_F(Channels, ShutdownUnderLoadStopsPromptlyAndCleansUp) {
  LineClient c;
  ASSERT_TRUE(c.connect_unix(daemon_->socket_path()));
  std::atomic<bool> stop{false};
  std::atomic<int> acked{0};
  std::thread load([&] {
    for (int i = 0; !stop.load(); ++i) {
      if (!c.send_line("G1 X" + std::to_string(10 + (i % 2)) + " F6000")) break;
      if (!c.read_until("ok", 5000)) break;  // skips "echo:busy" keepalives
      ++acked;
    }
  });
  // Load: the machine is moving and the host keeps its queue full.
  for (int i = 0; i < 1000 && acked.load() < 50; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_GE(acked.load(), 50);
  const auto t0 = std::chrono::steady_clock::now();
  daemon_->request_shutdown("test");
  thread_.join();
  const double stop_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  stop = true;
  load.join();
  EXPECT_LT(stop_s, 2.0);
  EXPECT_EQ(exit_code_, 0);
  EXPECT_FALSE(std::filesystem::exists(dir_ + "/feedloop.sock"));
  EXPECT_FALSE(std::filesystem::exists(dir_ + "/api.sock"));
  EXPECT_FALSE(std::filesystem::exists(dir_ + "/ttyFeedloop"));
}

}  // namespace
}  // namespace feedloop::testing
