// feedloopd as a process: config checking, signals (SIGHUP reload, SIGTERM), systemd
// notifications and watchdog, the systemd unit, and Printrun's pronsole printing a real file
// over the pty.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <sys/socket.h>
#include <sys/un.h>

#include <filesystem>
#include <fstream>
#include <regex>

#include "config/config.hpp"
#include "recorder/log_reader.hpp"
#include "tests/daemon/daemon_fixture.hpp"
#include "tests/daemon/line_client.hpp"
#include "tests/daemon/subprocess.hpp"

namespace feedloop::testing {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

void write_file(const std::string& path, const std::string& text) {
  std::ofstream(path) << text;
}

std::string read_file(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

class Process : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = make_temp_dir("proc"); }
  void TearDown() override { fs::remove_all(dir_); }
  // The embedded config with its name replaced; sockets go to ${RUNTIME_DIR} = dir_.
  std::string config_text(const std::string& name) {
    std::string yaml(config::default_config_yaml());
    yaml = std::regex_replace(yaml, std::regex("^name: .*$", std::regex::multiline),
                              "name: \"" + name + "\"");
    return yaml;
  }
  std::vector<std::string> env() { return {"RUNTIME_DIRECTORY=" + dir_, "STATE_DIRECTORY=" + dir_}; }
  json api_call(const std::string& method) {
    LineClient c;
    if (!c.connect_unix(dir_ + "/api.sock", 200)) return json();
    c.send_line(json{{"jsonrpc", "2.0"}, {"id", 1}, {"method", method}}.dump());
    auto line = c.read_line(5000);
    return line ? json::parse(*line) : json();
  }
  std::string dir_;
};

TEST_F(Process, CheckConfigReportsEveryProblemWithItsLocation) {
  const std::string path = dir_ + "/bad.yaml";
  std::string yaml = config_text("bad");
  const int lines = static_cast<int>(std::count(yaml.begin(), yaml.end(), '\n'));
  yaml += "planer:\n  max_velocity_mm_s: 5\n";
  write_file(path, yaml);
  Subprocess p({FEEDLOOPD_PATH, "--check-config", "--config", path}, {}, dir_ + "/out.txt");
  EXPECT_EQ(p.wait(20), 1);
  const std::string out = p.output();
  EXPECT_NE(out.find(path + ":" + std::to_string(lines + 1) + ":1:"), std::string::npos) << out;
  EXPECT_NE(out.find("planner"), std::string::npos) << out;  // the suggestion

  write_file(dir_ + "/good.yaml", config_text("good"));
  Subprocess ok({FEEDLOOPD_PATH, "--check-config", "--config", dir_ + "/good.yaml"}, {},
                dir_ + "/out2.txt");
  EXPECT_EQ(ok.wait(20), 0) << ok.output();

  // A log level spdlog does not know would silence the log ("off"): refused before anything starts.
  Subprocess typo({FEEDLOOPD_PATH, "--log-level", "wran", "--check-config"}, {},
                  dir_ + "/out3.txt");
  EXPECT_EQ(typo.wait(20), 2);
  EXPECT_NE(typo.output().find("--log-level must be trace, debug, info, warn or error, not 'wran'"),
            std::string::npos)
      << typo.output();
}

TEST_F(Process, SighupReloadsTheConfigAndSigtermStopsCleanly) {
  const std::string path = dir_ + "/printer.yaml";
  write_file(path, config_text("first"));
  Subprocess d({FEEDLOOPD_PATH, "--config", path}, env(), dir_ + "/daemon.log");
  ASSERT_TRUE(d.wait_for_output("ready", 20)) << d.output();
  EXPECT_EQ(api_call("info")["result"]["name"], "first");

  write_file(path, config_text("second"));
  d.signal(SIGHUP);
  std::string name;
  for (int i = 0; i < 200 && name != "second"; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    name = api_call("info")["result"].value("name", "");
  }
  EXPECT_EQ(name, "second");
  EXPECT_EQ(api_call("status")["result"]["config_reloads"], 1);

  write_file(path, "name: [unclosed\n");  // a broken config is refused; the running one stays
  d.signal(SIGHUP);
  ASSERT_TRUE(d.wait_for_output("config reload failed", 10)) << d.output();
  EXPECT_EQ(api_call("info")["result"]["name"], "second");

  d.signal(SIGTERM);
  EXPECT_EQ(d.wait(10), 0) << d.output();
  EXPECT_NE(d.output().find("feedloopd stopped"), std::string::npos);
  EXPECT_FALSE(fs::exists(dir_ + "/feedloop.sock"));
  EXPECT_FALSE(fs::exists(dir_ + "/ttyFeedloop"));
}

TEST_F(Process, NotifiesSystemdAndPetsTheWatchdogWhileHealthy) {
  const std::string notify_path = dir_ + "/notify";
  const int sock = ::socket(AF_UNIX, SOCK_DGRAM, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", notify_path.c_str());
  ASSERT_EQ(::bind(sock, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  timeval tv{0, 200000};
  ::setsockopt(sock, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  auto e = env();
  e.push_back("NOTIFY_SOCKET=" + notify_path);
  e.push_back("WATCHDOG_USEC=400000");
  Subprocess d({FEEDLOOPD_PATH}, e, dir_ + "/daemon.log");
  int ready = 0, pets = 0, stopping = 0;
  const auto t0 = std::chrono::steady_clock::now();
  while (std::chrono::steady_clock::now() - t0 < std::chrono::milliseconds(1500)) {
    char buf[512];
    const ssize_t n = ::recv(sock, buf, sizeof buf - 1, 0);
    if (n <= 0) continue;
    const std::string msg(buf, static_cast<size_t>(n));
    ready += msg.find("READY=1") != std::string::npos;
    pets += msg.find("WATCHDOG=1") != std::string::npos;
  }
  EXPECT_EQ(ready, 1);
  EXPECT_GE(pets, 8);  // every 100 ms for 1.5 s, minus start-up
  EXPECT_LE(pets, 16);
  d.signal(SIGTERM);
  for (int i = 0; i < 20 && !stopping; ++i) {
    char buf[512];
    const ssize_t n = ::recv(sock, buf, sizeof buf - 1, 0);
    if (n > 0) stopping += std::string(buf, static_cast<size_t>(n)).find("STOPPING=1") != std::string::npos;
  }
  EXPECT_EQ(stopping, 1);
  EXPECT_EQ(d.wait(10), 0);
  ::close(sock);
}

TEST_F(Process, SystemdUnitVerifies) {
  if (std::system("command -v systemd-analyze >/dev/null 2>&1") != 0)
    GTEST_SKIP() << "systemd-analyze not installed: the unit was NOT verified";
  const std::string unit = read_file(std::string(FEEDLOOP_SOURCE_DIR) + "/systemd/feedloopd.service");
  for (const char* key : {"Type=notify", "WatchdogSec=", "RuntimeDirectory=feedloop", "User=feedloop",
                          "LimitRTPRIO=", "LimitMEMLOCK=infinity", "DeviceAllow=char-ttyACM rw",
                          "ExecReload=/bin/kill -HUP $MAINPID"})
    EXPECT_NE(unit.find(key), std::string::npos) << key;
  EXPECT_EQ(unit.find("PrivateDevices=yes"), std::string::npos) << "would hide serial/USB devices";
  const std::string copy = dir_ + "/feedloopd.service";
  write_file(copy, std::regex_replace(unit, std::regex("/usr/bin/feedloopd"), FEEDLOOPD_PATH));
  Subprocess v({"systemd-analyze", "verify", copy}, {}, dir_ + "/verify.txt");
  EXPECT_EQ(v.wait(60), 0) << v.output();
  EXPECT_EQ(v.output(), "") << "systemd-analyze printed warnings";
}

// SIGTERM ends the daemon within 2 s whatever it is doing, and the print's recording is closed
// (every block readable, ending with the print_end event).
TEST_F(Process, SigtermEndsWithinTwoSecondsInEveryStateWithTheRecordingClosed) {
  struct State {
    const char* name;
    std::vector<std::string> lines;  // sent on the G-code socket before SIGTERM
    bool read_replies;               // false: a client that never reads
  };
  // A long diagonal at 20 mm/s: ~10 s of motion. A 2000-line flood fills the machine's queue
  // (the client is parked). M109 waits for a heater that takes ~5 s.
  std::vector<std::string> flood = {"G28"};
  for (int i = 0; i < 2000; ++i) flood.push_back("G1 X" + std::to_string(10 + (i % 2) * 100) + " F12000");
  const std::vector<State> states = {
      {"idle", {}, true},
      {"moving", {"G28", "G1 X200 Y200 F1200"}, true},
      {"heating (M109)", {"M109 S215"}, true},
      {"queue full, client parked", flood, true},
      {"client that never reads", flood, false},
  };
  for (const State& st : states) {
    SCOPED_TRACE(st.name);
    const std::string rec = dir_ + "/rec-" + std::to_string(&st - states.data());
    fs::create_directories(rec);
    const std::string yaml = config_text("sigterm");  // recordings go to ${STATE_DIR}/recordings = rec
    const std::string path = dir_ + "/printer.yaml";
    write_file(path, yaml);
    Subprocess d({FEEDLOOPD_PATH, "--config", path}, {"RUNTIME_DIRECTORY=" + dir_, "STATE_DIRECTORY=" + rec},
                 dir_ + "/daemon.log");
    ASSERT_TRUE(d.wait_for_output("ready", 20)) << d.output();
    LineClient c;
    ASSERT_TRUE(c.connect_unix(dir_ + "/feedloop.sock"));
    std::string all;
    for (const std::string& l : st.lines) all += l + "\n";
    std::thread writer([&] { c.send(all); });  // may block while the daemon is parked
    if (st.read_replies && !st.lines.empty() && st.lines[0] == "G28") c.read_until("ok", 5000);  // homed
    std::this_thread::sleep_for(std::chrono::milliseconds(700));
    if (!st.lines.empty()) {
      const json s = api_call("status");
      EXPECT_EQ(s["result"]["state"], "busy") << s.dump();
    }
    const auto t0 = std::chrono::steady_clock::now();
    d.signal(SIGTERM);
    const int rc = d.wait(5);
    const double took_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    c.close();  // unblocks the writer
    writer.join();
    EXPECT_EQ(rc, 0) << d.output();
    EXPECT_LT(took_s, 2.0) << d.output();
    std::printf("SIGTERM while %s: exited after %.3f s\n", st.name, took_s);
    if (st.lines.empty()) continue;  // no print, no recording
    // The recording: readable to the end, closed with print_end.
    std::vector<std::string> logs;
    for (const auto& e : fs::recursive_directory_iterator(rec))
      if (e.path().extension() == ".flrec") logs.push_back(e.path().string());
    ASSERT_FALSE(logs.empty()) << d.output();
    std::sort(logs.begin(), logs.end());
    auto r = recorder::LogReader::open(logs.back());
    ASSERT_TRUE(r) << r.error().to_string();
    bool ended = false;
    while (const recorder::DecodedRecord* rec_ = r->next())
      if (const auto* ev = std::get_if<recorder::EventRecord>(&rec_->record))
        ended = ended || ev->kind == recorder::EventKind::print_end;
    EXPECT_FALSE(r->error().has_value()) << r->error()->to_string();
    EXPECT_TRUE(ended) << logs.back();
    EXPECT_EQ(fs::status(logs.back()).permissions() & fs::perms::others_all, fs::perms::none);
  }
}

// Each peer is logged with its uid and pid (SO_PEERCRED); a world-writable runtime directory
// without the sticky bit stops the start with a message.
TEST_F(Process, PeersAreLoggedAndAnUnsafeRuntimeDirectoryIsRefused) {
  {
    Subprocess d({FEEDLOOPD_PATH}, env(), dir_ + "/daemon.log");
    ASSERT_TRUE(d.wait_for_output("ready", 20)) << d.output();
    LineClient c;
    ASSERT_TRUE(c.connect_unix(dir_ + "/feedloop.sock"));
    const std::string who = "uid " + std::to_string(::getuid()) + " gid " + std::to_string(::getgid()) +
                            " pid " + std::to_string(::getpid());
    EXPECT_TRUE(d.wait_for_output("socket#1 connected: " + who, 5)) << d.output();
    d.signal(SIGTERM);
    EXPECT_EQ(d.wait(10), 0);
  }
  const std::string run = dir_ + "/open";
  fs::create_directories(run);
  ASSERT_EQ(::chmod(run.c_str(), 0777), 0);
  Subprocess d({FEEDLOOPD_PATH}, {"RUNTIME_DIRECTORY=" + run, "STATE_DIRECTORY=" + dir_}, dir_ + "/daemon2.log");
  EXPECT_NE(d.wait(20), 0) << d.output();
  EXPECT_NE(d.output().find("has no sticky bit"), std::string::npos) << d.output();
  EXPECT_FALSE(fs::exists(run + "/feedloop.sock"));
}

// Printrun's pronsole (Debian package printrun) connects to the pty, sends a real sliced file
// line by line with its own host protocol and gets an ok for every line.
TEST_F(Process, PronsolePrintsARealFileOverThePty) {
#ifdef FEEDLOOP_SANITIZED
  GTEST_SKIP() << "13 minutes of simulated motion: runs in the optimized build only";
#endif
  const std::string gcode = std::string(FEEDLOOP_SHARED_DIR) + "/gcode/cube20_cartesian.gcode";
  if (!fs::exists(gcode)) GTEST_SKIP() << "corpus " << gcode << " absent: pronsole test skipped";
  if (std::system("command -v pronsole >/dev/null 2>&1") != 0)
    GTEST_SKIP() << "pronsole (Debian package printrun) not installed: test skipped";
  // The simulated printer in virtual time: the same pipeline, as fast as the CPU allows (the
  // cube takes 13 minutes of machine time).
  Subprocess d({FEEDLOOPD_PATH, "--virtual-time"}, env(), dir_ + "/daemon.log");
  ASSERT_TRUE(d.wait_for_output("ready", 20)) << d.output();
  const std::string link = dir_ + "/ttyFeedloop";
  Subprocess p({"pronsole", "-e", "connect " + link + " 250000", "-e", "load " + gcode, "-e", "print"},
               {"HOME=" + dir_, "DISPLAY="}, dir_ + "/pronsole.log");
  const bool ended = p.wait_for_output("Print ended", 600);  // ~140 s alone; a loaded machine doubles it
  ASSERT_TRUE(ended) << p.output().substr(0, 4000);
  EXPECT_EQ(p.output().find("Error:"), std::string::npos) << p.output().substr(0, 4000);
  // Every command line of the file was executed or answered by the daemon, none rejected.
  std::ifstream f(gcode);
  int64_t commands = 0;
  for (std::string line; std::getline(f, line);) {
    line = line.substr(0, line.find(';'));
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    if (line.rfind("M73", 0) == 0 || line.rfind("M117", 0) == 0 || line.rfind("M105", 0) == 0) continue;
    ++commands;
  }
  // "Print ended" is logged when the last line is sent; wait for its ok.
  json st = api_call("status");
  for (int i = 0; i < 100 && st["result"]["commands"]["executed"].get<int64_t>() < commands; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    st = api_call("status");
  }
  EXPECT_EQ(st["result"]["commands"]["rejected"], 0);
  EXPECT_EQ(st["result"]["commands"]["executed"].get<int64_t>(), commands);
  // The machine executed the whole print: ~13 minutes of motion.
  for (int i = 0; i < 200 && st["result"]["state"] != "idle"; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    st = api_call("status");
  }
  EXPECT_EQ(st["result"]["state"], "idle");
  EXPECT_GT(st["result"]["motion"]["print_time_s"].get<double>(), 600.0);
  EXPECT_NEAR(st["result"]["motion"]["print_time_s"].get<double>(),
              st["result"]["motion"]["planned_until_s"].get<double>(), 0.01);
  // (In virtual time the machine outruns pronsole's ~700 lines/s, so it stops and restarts when
  // the host pauses; motion_starts counts those restarts and is not asserted here.)
  p.write_stdin("exit force\n");  // pronsole turns the heaters off on exit
  p.close_stdin();
  p.wait(10);
  d.signal(SIGTERM);
  EXPECT_EQ(d.wait(10), 0);
}

}  // namespace
}  // namespace feedloop::testing
