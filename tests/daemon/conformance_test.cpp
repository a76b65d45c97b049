// Marlin behaviour a host sees through the daemon, each case naming the Marlin source it follows.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <regex>
#include <thread>

#include <nlohmann/json.hpp>

#include "tests/daemon/daemon_fixture.hpp"
#include "tests/daemon/json_call.hpp"
#include "tests/daemon/line_client.hpp"

namespace feedloop::testing {
namespace {

class Conformance : public DaemonFixture {};

// Marlin/src/gcode/host/M114.cpp + Marlin/src/module/stepper.cpp (Stepper::report_positions):
// "X:.. Y:.. Z:.. E:.. Count X:<steps> Y:<steps> Z:<steps>", the counts being each stepper's
// step counter (language.h: STR_COUNT_X " Count X:").
TEST_F(Conformance, M114CountsAreTheSteppersStepCounters) {
  LineClient c;
  ASSERT_TRUE(c.connect_unix(daemon_->socket_path()));
  for (const char* line : {"G28", "G1 X12.5 Y3 Z0.3 F6000", "M400"}) {
    ASSERT_TRUE(c.send_line(line));
    ASSERT_EQ(c.read_until("ok", 20000), "ok") << line;
  }
  ASSERT_TRUE(c.send_line("M114"));
  auto pos = c.read_until("X:", 5000);
  ASSERT_TRUE(pos);
  std::smatch m;
  ASSERT_TRUE(std::regex_match(*pos, m, std::regex(R"(X:12\.50 Y:3\.00 Z:0\.30 E:0\.00 Count X:(-?\d+) Y:(-?\d+) Z:(-?\d+))")))
      << *pos;
  const config::MachineConfig cfg = config::default_config();
  const double spm[3] = {cfg.axis("x")->steps_per_mm, cfg.axis("y")->steps_per_mm, cfg.axis("z")->steps_per_mm};
  const double mm[3] = {12.5, 3.0, 0.3};
  // The simulated printer runs closed loop: the steppers' counts carry the PI correction that
  // puts the carriage (its encoder) on the target, so they differ from mm x steps/mm by a little.
  for (int a = 0; a < 3; ++a) {
    EXPECT_GT(std::stoll(m[a + 1]), 0) << *pos;
    EXPECT_NEAR(static_cast<double>(std::stoll(m[a + 1])), mm[a] * spm[a], 0.03 * mm[a] * spm[a] + 2.0)
        << "axis " << a << ": " << *pos;
  }
  EXPECT_EQ(c.read_line(), "ok");
}

// "G10 S210 P0": Marlin (Marlin/src/gcode/feature/fwretract/G10_G11.cpp) accepts the line; as
// the temperature form it sets the hotend's target, as M104 S210 would, and moves nothing.
TEST_F(Conformance, G10TemperatureFormSetsTheHotendTarget) {
  LineClient c;
  ASSERT_TRUE(c.connect_unix(daemon_->socket_path()));
  ASSERT_TRUE(c.send_line("G10 S210 P0"));
  EXPECT_EQ(c.read_line(), "ok");
  ASSERT_TRUE(c.send_line("M105"));
  auto t = c.read_line();
  ASSERT_TRUE(t);
  EXPECT_NE(t->find("/210.0"), std::string::npos) << *t;
  ASSERT_TRUE(c.send_line("M114"));
  auto pos = c.read_until("X:", 5000);
  ASSERT_TRUE(pos);
  EXPECT_EQ(pos->rfind("X:0.00 Y:0.00 Z:0.00 E:0.00", 0), 0u) << *pos;
}

// A command's report reaches its host before its ok, on the Marlin socket and in the JSON API's
// gcode results ("reply"): Marlin's M302 without parameters (gcode/config/M302.cpp) reports the
// cold-extrusion state; M303's PID values travel the same way (ThermalMachine.M303...).
TEST_F(Conformance, ACommandsReportComesBeforeItsOk) {
  {
    LineClient c;
    ASSERT_TRUE(c.connect_unix(daemon_->socket_path()));
    ASSERT_TRUE(c.send_line("M302"));
    EXPECT_EQ(c.read_line(), "echo:Cold extrudes are disabled (min temp 170C)");
    EXPECT_EQ(c.read_line(), "ok");
    ASSERT_TRUE(c.send_line("M302 S180"));
    EXPECT_EQ(c.read_line(), "ok");  // a change reports nothing, as in Marlin
  }  // closed: the print's ownership is released for the API's client
  LineClient api;
  ASSERT_TRUE(api.connect_unix(daemon_->api_socket_path()));
  nlohmann::json r;
  for (int i = 0; i < 100; ++i) {  // the socket's close may reach the daemon after this request
    r = call(api, "gcode", {{"script", "M302 P1\nM302"}});
    if (!r.contains("error")) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_TRUE(r.contains("result")) << r.dump();
  const nlohmann::json& results = r["result"]["results"];
  ASSERT_EQ(results.size(), 2u) << r.dump();
  EXPECT_FALSE(results[0].contains("reply")) << r.dump();
  EXPECT_EQ(results[1].value("reply", ""), "echo:Cold extrudes are enabled (min temp 180C)")
      << r.dump();
}

// Marlin's M0 / M1 (gcode/lcd/M0_M1.cpp, with HOST_PROMPT_SUPPORT): the commands before it run,
// the text is shown and offered as a host prompt, and the host's next lines wait until an M108 (or
// M876, the prompt's answer) arrives; then M0's ok, and the lines go on in order. M0 P<ms> dwells.
TEST_F(Conformance, M0StopsForTheUserAndM108GoesOn) {
  LineClient c;
  ASSERT_TRUE(c.connect_unix(daemon_->socket_path()));
  for (const char* line : {"G28", "G1 X10 Y10 F6000"}) {
    ASSERT_TRUE(c.send_line(line));
    ASSERT_EQ(c.read_until("ok", 20000), "ok") << line;
  }
  ASSERT_TRUE(c.send_line("M0 Swap the nozzle"));  // "Swap" is text, not an S word
  EXPECT_EQ(c.read_line(20000), "echo:Swap the nozzle; send M108 to continue");
  EXPECT_EQ(c.read_line(), "//action:prompt_end");
  EXPECT_EQ(c.read_line(), "//action:prompt_begin Swap the nozzle");
  EXPECT_EQ(c.read_line(), "//action:prompt_button Continue");
  EXPECT_EQ(c.read_line(), "//action:prompt_show");
  ASSERT_TRUE(c.send_line("G1 X20"));
  // Nothing moves and nothing is answered while the user's turn lasts (the keepalive aside).
  for (int i = 0; i < 3; ++i) {
    const auto l = c.read_line(300);
    if (l) {
      EXPECT_EQ(*l, "echo:busy: paused for user");
    }
  }
  LineClient other;
  ASSERT_TRUE(other.connect_unix(daemon_->socket_path()));
  ASSERT_TRUE(other.send_line("M114"));
  auto pos = other.read_until("X:", 5000);
  ASSERT_TRUE(pos);
  EXPECT_EQ(pos->rfind("X:10.00 Y:10.00", 0), 0u) << *pos;
  EXPECT_EQ(other.read_line(), "ok");
  // The status shows the stop's text; a config reload waits for the answer (the rebuilt machine
  // would not know where the stop left the head).
  LineClient api;
  ASSERT_TRUE(api.connect_unix(daemon_->api_socket_path()));
  nlohmann::json st = call(api, "status", nlohmann::json::object());
  ASSERT_TRUE(st.contains("result")) << st.dump();
  EXPECT_EQ(st["result"].value("message", ""), "Swap the nozzle");
  const int reloads = st["result"].value("config_reloads", -1);
  ASSERT_TRUE(call(api, "config.reload", nlohmann::json::object()).contains("result"));
  std::this_thread::sleep_for(std::chrono::milliseconds(600));
  EXPECT_EQ(call(api, "status", nlohmann::json::object())["result"].value("config_reloads", -1),
            reloads);
  ASSERT_TRUE(c.send_line("M108"));
  EXPECT_EQ(c.read_until("//action:prompt_end", 5000), "//action:prompt_end");
  EXPECT_EQ(c.read_line(), "ok");              // M0's
  EXPECT_EQ(c.read_until("ok", 20000), "ok");  // G1 X20's
  EXPECT_EQ(c.read_until("ok", 5000), "ok");   // M108's
  ASSERT_TRUE(c.send_line("M400"));
  ASSERT_EQ(c.read_until("ok", 20000), "ok");
  ASSERT_TRUE(c.send_line("M114"));
  pos = c.read_until("X:", 5000);
  ASSERT_TRUE(pos);
  EXPECT_EQ(pos->rfind("X:20.00 Y:10.00", 0), 0u) << *pos;
  EXPECT_EQ(c.read_line(), "ok");
  int reloaded = -1;  // the reload, once the stop was answered and the machine is idle again
  for (int i = 0; i < 100 && reloaded != reloads + 1; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    reloaded = call(api, "status", nlohmann::json::object())["result"].value("config_reloads", -1);
  }
  EXPECT_EQ(reloaded, reloads + 1);
  // A timed stop is a dwell: its ok comes by itself, no prompt.
  ASSERT_TRUE(c.send_line("M0 P50"));
  EXPECT_EQ(c.read_line(5000), "ok");
}

// Marlin's M600 (gcode/feature/pause/M600.cpp, feature/pause.cpp): from a host's stream, the head
// retracts, rises and parks (the job pause's settings), the user loads the filament, and the
// answer (M876 from the host prompt, here from another client) brings it back over XY, then Z,
// primes, and restores the host's G91 / M83 and G20 so its next relative move (in inches) goes on
// from where it was.
TEST_F(Conformance, M600FromAHostParksAndReturnsWithTheHostsModes) {
  LineClient c;
  ASSERT_TRUE(c.connect_unix(daemon_->socket_path()));
  for (const char* line :
       {"G28", "M302 P1", "G1 X30 Y40 Z1 F6000", "G91", "M83", "G1 E2 F600", "G20"}) {
    ASSERT_TRUE(c.send_line(line));
    ASSERT_EQ(c.read_until("ok", 20000), "ok") << line;
  }
  ASSERT_TRUE(c.send_line("M600"));
  EXPECT_EQ(c.read_until("echo:filament change", 30000),
            "echo:filament change (M600): load the new filament; send M108 to continue");
  EXPECT_EQ(c.read_until("//action:prompt_show", 3000), "//action:prompt_show");
  const config::MachineConfig cfg = config::default_config();
  LineClient other;
  ASSERT_TRUE(other.connect_unix(daemon_->socket_path()));
  ASSERT_TRUE(other.send_line("M114"));
  auto pos = other.read_until("X:", 5000);
  ASSERT_TRUE(pos);
  // Marlin's NOZZLE_PARK_POINT default: X min + 10, Y max - 10; Z up by the lift (5 mm); E back by
  // the pause's retract (1 mm).
  char parked[96];
  std::snprintf(parked, sizeof parked, "X:%.2f Y:%.2f Z:6.00 E:1.00", cfg.axis("x")->min_mm + 10.0,
                cfg.axis("y")->max_mm - 10.0);
  EXPECT_EQ(pos->rfind(parked, 0), 0u) << *pos;
  EXPECT_EQ(other.read_line(), "ok");
  ASSERT_TRUE(other.send_line("M876 S0"));
  EXPECT_EQ(other.read_line(5000), "ok");
  EXPECT_EQ(c.read_until("//action:prompt_end", 5000), "//action:prompt_end");
  EXPECT_EQ(c.read_until("ok", 30000), "ok");   // M600's, once the head is back
  ASSERT_TRUE(c.send_line("G1 X1 E0.1 F20"));   // still relative and in inches, as the host left it
  ASSERT_EQ(c.read_until("ok", 20000), "ok");
  ASSERT_TRUE(c.send_line("M400"));
  ASSERT_EQ(c.read_until("ok", 20000), "ok");
  ASSERT_TRUE(c.send_line("M114"));
  pos = c.read_until("X:", 5000);
  ASSERT_TRUE(pos);
  EXPECT_EQ(pos->rfind("X:55.40 Y:40.00 Z:1.00 E:4.54", 0), 0u) << *pos;
}

// Marlin's M220 / M221 without a value report the factor (gcode/config/M220.cpp: "FR:100%";
// M221.cpp: "echo:E0 Flow: 100%"), after the commands before them have run; B and R back the
// speed factor up and restore it.
TEST_F(Conformance, M220AndM221WithoutAValueReportTheFactor) {
  LineClient c;
  ASSERT_TRUE(c.connect_unix(daemon_->socket_path()));
  auto ask = [&](const char* line) {
    std::string all;
    if (!c.send_line(line)) return all;
    for (int i = 0; i < 3; ++i) {
      auto l = c.read_line();
      if (!l) break;
      all += *l + "\n";
      if (*l == "ok") break;
    }
    return all;
  };
  EXPECT_EQ(ask("M220"), "FR:100%\nok\n");
  EXPECT_EQ(ask("M221"), "echo:E0 Flow: 100%\nok\n");
  EXPECT_EQ(ask("M220 S150"), "ok\n");
  EXPECT_EQ(ask("M221 S95"), "ok\n");
  EXPECT_EQ(ask("M220"), "FR:150%\nok\n");
  EXPECT_EQ(ask("M221"), "echo:E0 Flow: 95%\nok\n");
  EXPECT_EQ(ask("M220 B"), "ok\n");
  EXPECT_EQ(ask("M220 S50"), "ok\n");
  EXPECT_EQ(ask("M220"), "FR:50%\nok\n");
  EXPECT_EQ(ask("M220 R"), "ok\n");
  EXPECT_EQ(ask("M220"), "FR:150%\nok\n");
}

// Marlin 1.0.x Marlin_main.cpp get_command(): a checksum without N is refused; and the Klipper
// command gets its clear error, with the line's ok (the connection goes on).
TEST_F(Conformance, RefusedLinesGetAnErrorAndTheirOk) {
  LineClient c;
  ASSERT_TRUE(c.connect_unix(daemon_->socket_path()));
  std::string s = "G1 X5";
  unsigned cs = 0;
  for (char ch : s) cs ^= static_cast<unsigned char>(ch);
  ASSERT_TRUE(c.send_line(s + "*" + std::to_string(cs)));
  EXPECT_EQ(c.read_line(), "Error:No Line Number with checksum, Last Line: 0");
  EXPECT_EQ(c.read_line(), "ok");
  ASSERT_TRUE(c.send_line("SET_VELOCITY_LIMIT VELOCITY=300"));
  auto e = c.read_line();
  ASSERT_TRUE(e);
  EXPECT_NE(e->find("Klipper extended command"), std::string::npos) << *e;
  EXPECT_EQ(c.read_line(), "ok");
  ASSERT_TRUE(c.send_line("G1 X 30 F3000"));  // Marlin/src/gcode/parser.cpp: blanks skipped
  EXPECT_EQ(c.read_line(), "ok");
}

// Marlin/src/gcode/control/M999.cpp: after a stop (M112 here) the printer refuses commands until
// M999 returns it to running. feedloop rebuilds the machine from the running config, as Klipper's
// FIRMWARE_RESTART does (klippy/klippy.py): the stop cleared, the heaters off, the axes unhomed;
// M999's ok comes once the new machine runs, so the next line runs on it.
TEST_F(Conformance, M999AfterAnEmergencyStopRebuildsTheMachine) {
  LineClient c;
  ASSERT_TRUE(c.connect_unix(daemon_->socket_path()));
  ASSERT_TRUE(c.send_line("M999"));  // not stopped: ok, nothing changes
  EXPECT_EQ(c.read_line(), "ok");
  for (const char* line : {"G28", "M104 S200", "G1 X20 Y10 F6000", "M400"}) {
    ASSERT_TRUE(c.send_line(line));
    ASSERT_EQ(c.read_until("ok", 20000), "ok") << line;
  }
  ASSERT_TRUE(c.send_line("M112"));
  EXPECT_EQ(c.read_line(), "Error:Printer halted. kill() called!");
  ASSERT_TRUE(c.send_line("G1 X30"));
  auto refused = c.read_line();
  ASSERT_TRUE(refused);
  EXPECT_NE(refused->find("send M999"), std::string::npos) << *refused;
  EXPECT_EQ(c.read_line(), "ok");
  ASSERT_TRUE(c.send_line("M999"));
  EXPECT_EQ(c.read_until("ok", 20000), "ok");
  // The new machine: the hotend's target is 0 and it homes and moves.
  ASSERT_TRUE(c.send_line("M105"));
  auto temps = c.read_until("ok T:", 5000);
  ASSERT_TRUE(temps);
  EXPECT_NE(temps->find(" /0.0 "), std::string::npos) << *temps;
  for (const char* line : {"G28", "G1 X30 Y5 F6000", "M400"}) {
    ASSERT_TRUE(c.send_line(line));
    ASSERT_EQ(c.read_until("ok", 20000), "ok") << line;
  }
  ASSERT_TRUE(c.send_line("M114"));
  auto pos = c.read_until("X:", 5000);
  ASSERT_TRUE(pos);
  EXPECT_EQ(pos->rfind("X:30.00 Y:5.00", 0), 0u) << *pos;
}

// A client that leaves with a line still waiting for room in the machine's queue (a host that
// streamed slow moves, then vanished): that line goes with it. Its ticket stayed pending, and
// M999 after an M112 from another client waited for nothing pending for good: no answer, the
// machine halted until the daemon restarted (found by a hostile client, 300 lines at F60).
TEST_F(Conformance, M999AfterAClientLeftWithALineWaitingForQueueRoom) {
  {
    LineClient a;
    ASSERT_TRUE(a.connect_unix(daemon_->socket_path()));
    ASSERT_TRUE(a.send_line("G28"));
    ASSERT_EQ(a.read_until("ok", 20000), "ok");
    for (int i = 0; i < 300; ++i) ASSERT_TRUE(a.send_line(i % 2 ? "G1 X10 F60" : "G1 X200 F60"));
    // Until the queue is full: the oks stop coming (a line parked) after fewer than 300.
    int oks = 0;
    while (a.read_until("ok", 1000)) ++oks;
    ASSERT_LT(oks, 300);
  }  // a leaves
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  LineClient b;
  ASSERT_TRUE(b.connect_unix(daemon_->socket_path()));
  ASSERT_TRUE(b.send_line("M112"));
  EXPECT_EQ(b.read_line(), "Error:Printer halted. kill() called!");
  ASSERT_TRUE(b.send_line("M999"));
  EXPECT_EQ(b.read_until("ok", 20000), "ok");
  ASSERT_TRUE(b.send_line("G28"));
  EXPECT_EQ(b.read_until("ok", 20000), "ok");
}

// M112 is an emergency stop from every channel, not only the Marlin socket: a JSON script (the
// web's console goes the same way) stops the machine at once, ahead of the script's lines before
// it, and runs none of them. It was taken for a queued no-op and answered ok, the moves after it
// ran.
TEST_F(Conformance, M112InAJsonScriptStopsTheMachine) {
  LineClient api;
  ASSERT_TRUE(api.connect_unix(daemon_->api_socket_path()));
  const nlohmann::json run = call(api, "gcode", {{"script", "G1 X40 F6000\nm112\nG1 X50 F6000"}});
  ASSERT_TRUE(run.contains("result")) << run.dump();
  ASSERT_EQ(run["result"]["results"].size(), 1u) << run.dump();
  EXPECT_EQ(run["result"]["results"][0]["reply"], "Error:Printer halted. kill() called!");
  const nlohmann::json st = call(api, "status");
  EXPECT_EQ(st["result"]["state"], "emergency_stopped") << st.dump();
  EXPECT_DOUBLE_EQ(st["result"]["position_mm"]["x"].get<double>(), 0.0);
  const nlohmann::json after = call(api, "gcode", {{"script", "G1 X5"}});
  ASSERT_TRUE(after.contains("error")) << after.dump();
  EXPECT_NE(after["error"]["message"].get<std::string>().find("M999"), std::string::npos);
}

// Marlin/src/gcode/feature/advance/M900.cpp: "M900 K<k>" sets the linear advance factor (0..10)
// and answers ok; "M900" alone reports "Advance K=<k>" (one extruder). Klipper's
// SET_PRESSURE_ADVANCE (klippy/kinematics/extruder.py) sets both values; a bad value is refused
// with its location and changes nothing; the JSON status carries the values.
TEST_F(Conformance, M900AndSetPressureAdvance) {
  LineClient c;
  ASSERT_TRUE(c.connect_unix(daemon_->socket_path()));
  ASSERT_TRUE(c.send_line("M900"));
  EXPECT_EQ(c.read_line(), "echo:Advance K=0.000");
  EXPECT_EQ(c.read_line(), "ok");
  ASSERT_TRUE(c.send_line("M900 K0.045"));
  EXPECT_EQ(c.read_line(), "ok");
  ASSERT_TRUE(c.send_line("M900"));
  EXPECT_EQ(c.read_line(), "echo:Advance K=0.045");
  EXPECT_EQ(c.read_line(), "ok");
  ASSERT_TRUE(c.send_line("SET_PRESSURE_ADVANCE ADVANCE=0.5 SMOOTH_TIME=0.3"));
  auto e = c.read_line();
  ASSERT_TRUE(e);
  EXPECT_NE(e->find("SMOOTH_TIME must be in (0, 0.200] s"), std::string::npos) << *e;
  EXPECT_EQ(e->rfind("Error:", 0), 0u) << *e;
  EXPECT_EQ(c.read_line(), "ok");
  ASSERT_TRUE(c.send_line("SET_PRESSURE_ADVANCE ADVANCE=0.06 SMOOTH_TIME=0.03"));
  EXPECT_EQ(c.read_line(), "ok");
  ASSERT_TRUE(c.send_line("SET_PRESSURE_ADVANCE"));
  EXPECT_EQ(c.read_line(), "// pressure_advance: 0.060000");
  EXPECT_EQ(c.read_line(), "// pressure_advance_smooth_time: 0.030000");
  EXPECT_EQ(c.read_line(), "ok");
}

// The shipped default printer refuses motion before homing, as Klipper ("Must home axis first",
// klippy/kinematics/cartesian.py) and Marlin with NO_MOTION_BEFORE_HOMING do; M84 (Marlin
// M18_M84.cpp: the disabled axes are no longer trusted) asks for homing again. The JSON API's
// status says which axes are homed (Moonraker's toolhead.homed_axes).
class ShippedDefault : public DaemonFixture {
  void customize(config::MachineConfig& cfg) override {
    cfg.planner.allow_moves_before_homing =
        config::default_config().planner.allow_moves_before_homing;
  }
};

// An M600 before the axes are homed (moves before homing refused, the shipped default) parks
// nothing: the park would be refused midway, after its retract. An error, then its ok, and the
// host's next line runs.
TEST_F(ShippedDefault, M600BeforeHomingIsRefusedWholeAndTheNextLineRuns) {
  LineClient c;
  ASSERT_TRUE(c.connect_unix(daemon_->socket_path()));
  ASSERT_TRUE(c.send_line("M600"));
  EXPECT_EQ(c.read_line(10000),
            "Error:M600: the axes are not homed (send G28 first); nothing moved");
  EXPECT_EQ(c.read_line(), "ok");
  ASSERT_TRUE(c.send_line("M114"));
  auto pos = c.read_until("X:", 5000);
  ASSERT_TRUE(pos);
  EXPECT_EQ(pos->rfind("X:0.00 Y:0.00 Z:0.00 E:0.00", 0), 0u) << *pos;
  EXPECT_EQ(c.read_line(), "ok");
}

TEST_F(ShippedDefault, MoveBeforeHomingIsRefusedUntilG28) {
  EXPECT_FALSE(config::default_config().planner.allow_moves_before_homing);
  auto homed_axes = [&]() -> std::string {
    LineClient api;
    if (!api.connect_unix(daemon_->api_socket_path())) return "?";
    api.send_line(R"({"jsonrpc":"2.0","id":1,"method":"status"})");
    for (int i = 0; i < 50; ++i) {
      auto line = api.read_line(5000);
      if (!line) return "?";
      auto j = nlohmann::json::parse(*line, nullptr, false);
      if (j.is_object() && j.contains("id")) return j["result"].value("homed_axes", "?");
    }
    return "?";
  };
  // The status is a snapshot taken at most status_period_ms ago: poll until it shows `want`.
  auto wait_homed = [&](const std::string& want) {
    std::string got;
    for (int i = 0; i < 60; ++i) {
      got = homed_axes();
      if (got == want) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return got;
  };
  LineClient c;
  ASSERT_TRUE(c.connect_unix(daemon_->socket_path()));
  EXPECT_EQ(wait_homed(""), "");
  ASSERT_TRUE(c.send_line("G1 X5 Y5 F3000"));
  auto e = c.read_line();
  ASSERT_TRUE(e);
  EXPECT_NE(e->find("Must home axis first (XY not homed"), std::string::npos) << *e;
  EXPECT_EQ(c.read_line(), "ok");
  ASSERT_TRUE(c.send_line("G1 E1 F300"));  // the extruder needs no homing
  EXPECT_EQ(c.read_until("ok", 5000), "ok");
  for (const char* line : {"G28", "G1 X5 Y5 F3000", "M400"}) {
    ASSERT_TRUE(c.send_line(line));
    ASSERT_EQ(c.read_until("ok", 20000), "ok") << line;
  }
  EXPECT_EQ(wait_homed("xyz"), "xyz");
  ASSERT_TRUE(c.send_line("M84"));
  EXPECT_EQ(c.read_until("ok", 5000), "ok");
  EXPECT_EQ(wait_homed(""), "");
  ASSERT_TRUE(c.send_line("G1 X6"));
  auto e2 = c.read_line();
  ASSERT_TRUE(e2);
  EXPECT_NE(e2->find("Must home axis first (X not homed"), std::string::npos) << *e2;
}

// M119 as Marlin answers it (gcode/host/M119.cpp, endstops.cpp report_states): "Reporting endstop
// status", one "x_min: open" / "TRIGGERED" line per switch, then ok. The simulated carriages start
// 2 mm from their switches (open); after G28 each stopped on its switch (TRIGGERED); a move away
// opens it again. The JSON status shows each axis's homed position from its switch.
TEST_F(ShippedDefault, M119ReportsTheSwitchesAndTheStatusTheHomedPositions) {
  LineClient c;
  ASSERT_TRUE(c.connect_unix(daemon_->socket_path()));
  auto m119 = [&]() {
    std::string all;
    if (!c.send_line("M119")) return all;
    for (int i = 0; i < 6; ++i) {
      auto line = c.read_line();
      if (!line) break;
      all += *line + "\n";
      if (*line == "ok") break;
    }
    return all;
  };
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // MCUs ready, switches queried
  EXPECT_EQ(m119(), "Reporting endstop status\nx_min: open\ny_min: open\nz_min: open\nok\n");
  ASSERT_TRUE(c.send_line("G28"));
  ASSERT_EQ(c.read_until("ok", 20000), "ok");
  EXPECT_EQ(m119(),
            "Reporting endstop status\nx_min: TRIGGERED\ny_min: TRIGGERED\nz_min: TRIGGERED\nok\n");
  for (const char* line : {"G1 X10 F3000", "M400", "G4 P300"}) {
    ASSERT_TRUE(c.send_line(line));
    ASSERT_EQ(c.read_until("ok", 20000), "ok") << line;
  }
  EXPECT_EQ(m119(),
            "Reporting endstop status\nx_min: open\ny_min: TRIGGERED\nz_min: TRIGGERED\nok\n");
  LineClient api;
  ASSERT_TRUE(api.connect_unix(daemon_->api_socket_path()));
  nlohmann::json homing;
  for (int k = 0; k < 40 && !(homing.is_object() && homing.value("homings", 0) == 1); ++k) {
    api.send_line(R"({"jsonrpc":"2.0","id":1,"method":"status"})");
    for (int i = 0; i < 50; ++i) {
      auto line = api.read_line(5000);
      if (!line) break;
      auto j = nlohmann::json::parse(*line, nullptr, false);
      if (j.is_object() && j.contains("id")) {
        homing = j["result"]["homing"];
        break;
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ASSERT_TRUE(homing.is_object());
  EXPECT_EQ(homing.value("homings", 0), 1);
  for (const char* axis : {"x", "y", "z"}) {
    ASSERT_TRUE(homing["homed_position_mm"][axis].is_number()) << homing.dump();
    const double mm = homing["homed_position_mm"][axis].get<double>();
    // position_endstop 0: Z (steps-referenced) a few steps past it at most; X and Y home to their
    // carriages (linear encoders, docs/homing.md), which rest behind the switch by the lag the
    // stop left (-0.078 and -0.054 mm measured on the default printer).
    EXPECT_LE(mm, 0.0) << axis;
    EXPECT_GT(mm, std::string(axis) == "z" ? -0.02 : -0.15) << axis;
  }
  EXPECT_EQ(homing["endstops"].value("x_min", ""), "open");
}

}  // namespace
}  // namespace feedloop::testing
