// The web server inside feedloopd (docs/web.md) and the daemon's one print job (docs/jobs.md):
// a file uploaded from the web is the job folder's file; a print started over the Marlin socket
// (M32) shows in the web's print_stats, is paused from the web and resumed with M24; a print
// started from the web shows in the JSON API's job.status and is cancelled there. Then what the
// web shows of the machine besides: the part fan from M106, the heaters' power, the console echo
// of another channel's lines, a print streamed over the socket in print_stats, and the last
// calibration report for feedloop's page.
#include <gtest/gtest.h>

#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "../planner/planner_test_util.hpp"
#include "daemon/job_files.hpp"
#include "daemon_fixture.hpp"
#include "tests/daemon/json_call.hpp"
#include "tests/daemon/line_client.hpp"

namespace feedloop::testing {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
using nlohmann::json;

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

struct Reply {
  int status = 0;
  json body;
};

// One HTTP request to the daemon's web server.
Reply request(uint16_t port, http::verb verb, const std::string& target,
              const std::string& body = {}, const std::string& content_type = "application/json") {
  asio::io_context io;
  asio::ip::tcp::socket s(io);
  s.connect({asio::ip::make_address("127.0.0.1"), port});
  http::request<http::string_body> req{verb, target, 11};
  req.set(http::field::host, "127.0.0.1");
  if (!body.empty()) {
    req.set(http::field::content_type, content_type);
    req.body() = body;
  }
  req.prepare_payload();
  http::write(s, req);
  beast::flat_buffer buf;
  http::response<http::string_body> res;
  http::read(s, buf, res);
  return {static_cast<int>(res.result_int()), json::parse(res.body(), nullptr, false)};
}

class WebJobs : public DaemonFixture {
 protected:
  void customize(config::MachineConfig& cfg) override {
    cfg.jobs.directory = dir_ + "/gcodes";
    cfg.recorder.enabled = false;
    cfg.web.enabled = true;
    cfg.web.port = 0;
    cfg.web.files_dir = dir_ + "/files";
    cfg.web.database = dir_ + "/web.sqlite";
    cfg.web.calibration_dir = dir_ + "/ident";
  }
  uint16_t port() const { return daemon_->web_port(); }
  json objects(const std::string& query) {
    Reply r = request(port(), http::verb::get, "/printer/objects/query?" + query);
    EXPECT_EQ(r.status, 200) << r.body.dump();
    return r.body["result"]["status"];
  }
  template <class Pred>
  json wait_objects(const std::string& query, Pred pred, int timeout_s) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(timeout_s);
    json s;
    while (std::chrono::steady_clock::now() < deadline) {
      s = objects(query);
      if (pred(s)) return s;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return s;
  }
  std::string multipart(const std::string& name, const std::string& content) {
    return "--XyZ\r\nContent-Disposition: form-data; name=\"root\"\r\n\r\ngcodes\r\n"
           "--XyZ\r\nContent-Disposition: form-data; name=\"file\"; filename=\"" +
           name + "\"\r\nContent-Type: application/octet-stream\r\n\r\n" + content +
           "\r\n--XyZ--\r\n";
  }
};

class WebJobsVirtual : public WebJobs {
 protected:
  bool virtual_time() const override { return true; }
};

// The filament the cube moves, from the planner's own interpreter (its machine E, which G92 does
// not move): what print_stats.filament_used must say.
double filament_of(const std::string& text) {
  planner::test::Rig rig{planner::test::cartesian_config()};
  const double e0 = rig.interp.state().machine_mm[planner::kE];
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) (void)rig.run(l);
  return rig.interp.state().machine_mm[planner::kE] - e0;
}

TEST_F(WebJobsVirtual, OnePrintJobWhicheverChannelStartsPausesOrCancelsIt) {
  const std::string text =
      read_file(std::string(FEEDLOOP_SOURCE_DIR) + "/examples/gcode/cube20_3layers.gcode");
  ASSERT_GT(text.size(), 1000u);
  // Uploaded from the web (Mainsail's multipart POST): it is the job folder's file.
  Reply up = request(port(), http::verb::post, "/server/files/upload",
                     multipart("cube.gcode", text), "multipart/form-data; boundary=XyZ");
  ASSERT_EQ(up.status, 201) << up.body.dump();
  EXPECT_EQ(read_file(dir_ + "/gcodes/cube.gcode"), text);
  LineClient api;
  ASSERT_TRUE(api.connect_unix(daemon_->api_socket_path()));
  json files = call(api, "files.list");
  ASSERT_EQ(files["result"]["files"].size(), 1u) << files.dump();
  EXPECT_EQ(files["result"]["files"][0]["filename"], "cube.gcode");

  // Started over the Marlin socket (M32), shown by the web.
  LineClient marlin;
  ASSERT_TRUE(marlin.connect_unix(daemon_->socket_path()));
  ASSERT_TRUE(marlin.send_line("M32 !cube.gcode#"));
  ASSERT_TRUE(marlin.read_until("ok", 5000));
  json s = wait_objects(
      "print_stats&virtual_sdcard",
      [](const json& o) { return o["virtual_sdcard"]["file_position"].get<uint64_t>() > 0; }, 30);
  EXPECT_EQ(s["print_stats"]["state"], "printing") << s.dump();
  EXPECT_EQ(s["print_stats"]["filename"], "cube.gcode");
  EXPECT_EQ(s["virtual_sdcard"]["file_path"], dir_ + "/gcodes/cube.gcode");
  EXPECT_EQ(s["virtual_sdcard"]["file_size"], text.size());

  // Paused from the web: the JSON API and M27 see the same job paused.
  Reply pause = request(port(), http::verb::post, "/printer/print/pause");
  ASSERT_EQ(pause.status, 200) << pause.body.dump();
  s = wait_objects(
      "print_stats&pause_resume",
      [](const json& o) { return o["print_stats"]["state"] == "paused"; }, 10);
  EXPECT_TRUE(s["pause_resume"]["is_paused"].get<bool>());
  json j;
  for (int i = 0; i < 200; ++i) {
    j = call(api, "job.status")["result"];
    if (j["state"] == "paused") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ASSERT_EQ(j["state"], "paused") << j.dump();
  EXPECT_EQ(j["filename"], "cube.gcode");
  EXPECT_EQ(j["pauses"], 1);
  const uint64_t paused_at = j["position_bytes"].get<uint64_t>();
  EXPECT_GT(paused_at, 0u);
  EXPECT_LT(paused_at, text.size());
  EXPECT_EQ(objects("virtual_sdcard")["virtual_sdcard"]["file_position"], paused_at);
  // Resumed from the socket (M24): the web shows it printing again.
  ASSERT_TRUE(marlin.send_line("M24"));
  ASSERT_TRUE(marlin.read_until("ok", 5000));
  s = wait_objects(
      "print_stats", [](const json& o) { return o["print_stats"]["state"] != "paused"; }, 10);
  EXPECT_TRUE(s["print_stats"]["state"] == "printing" || s["print_stats"]["state"] == "complete")
      << s.dump();
  s = wait_objects(
      "print_stats&virtual_sdcard",
      [](const json& o) { return o["print_stats"]["state"] != "printing"; }, 300);
  ASSERT_EQ(s["print_stats"]["state"], "complete") << s.dump();
  EXPECT_EQ(s["virtual_sdcard"]["file_position"], text.size());
  // filament_used: the planner's E over the file (the pause's retract and prime not counted).
  const double filament = filament_of(text);
  EXPECT_GT(filament, 50.0);  // three layers of a 20 mm cube
  EXPECT_NEAR(s["print_stats"]["filament_used"].get<double>(), filament, 1e-6);
  EXPECT_GT(s["print_stats"]["print_duration"].get<double>(), 0.0);
  EXPECT_LE(s["print_stats"]["print_duration"].get<double>(),
            s["print_stats"]["total_duration"].get<double>());
  j = call(api, "job.status")["result"];
  EXPECT_EQ(j["state"], "complete");
  EXPECT_NEAR(j["filament_used_mm"].get<double>(), filament, 1e-6);
  std::printf("cube: filament used %.3f mm (planner: %.3f mm), paused at byte %llu of %zu\n",
              s["print_stats"]["filament_used"].get<double>(), filament,
              static_cast<unsigned long long>(paused_at), text.size());

  // Started from the web, cancelled over the JSON API.
  Reply start = request(port(), http::verb::post, "/printer/print/start?filename=cube.gcode");
  ASSERT_EQ(start.status, 200) << start.body.dump();
  j = call(api, "job.status")["result"];
  EXPECT_EQ(j["state"], "printing") << j.dump();
  EXPECT_EQ(j["filename"], "cube.gcode");
  // Another start while it runs: refused, from either side.
  Reply again = request(port(), http::verb::post, "/printer/print/start?filename=cube.gcode");
  EXPECT_EQ(again.status, 400) << again.body.dump();
  EXPECT_NE(again.body.dump().find("cancel it first"), std::string::npos) << again.body.dump();
  json cancel = call(api, "job.cancel");
  ASSERT_TRUE(cancel.contains("result")) << cancel.dump();
  s = wait_objects(
      "print_stats", [](const json& o) { return o["print_stats"]["state"] != "printing"; }, 60);
  EXPECT_EQ(s["print_stats"]["state"], "cancelled") << s.dump();
  // The web's history has both, as Moonraker records virtual_sdcard prints.
  Reply hist = request(port(), http::verb::get, "/server/history/list?limit=5");
  ASSERT_EQ(hist.status, 200);
  const json& jobs = hist.body["result"]["jobs"];
  ASSERT_EQ(jobs.size(), 2u) << hist.body.dump();
  EXPECT_EQ(jobs[0]["status"], "cancelled");
  EXPECT_EQ(jobs[1]["status"], "completed");
  EXPECT_NEAR(jobs[1]["filament_used"].get<double>(), filament, 1e-6);
}

// Two labelled objects, as PrusaSlicer and OrcaSlicer label them for a Klipper printer, and a
// pause in the file (M601) after their definitions. While the job is paused, the web (Mainsail's
// "exclude object") excludes B although the print job owns the print; the web's exclude_object
// lists both objects and B excluded. Resumed, the job completes and B's moves are not planned:
// the machine planned as many moves as the planner's own interpreter plans for the rest of the file
// with B excluded, 24 fewer than with B, plus the job's own: the first resume's way back (3 moves)
// and a second pause in the file inside B (excluded): its park (3) and way back (3) move although
// B's moves are skipped, and B's moves after it stay skipped. The next print starts with no
// object excluded.
std::string two_objects_gcode() {
  std::string g = "G28\nM302 P1\nM83\nG1 Z0.3 F600\n";  // cold extrusion: nothing heats here
  g += "EXCLUDE_OBJECT_DEFINE NAME='part a' CENTER=60,60 POLYGON=[[50,50],[70,50],[70,70]]\n";
  g += "EXCLUDE_OBJECT_DEFINE NAME=part_b CENTER=150,150\nM601\n";
  for (int layer = 0; layer < 3; ++layer) {
    const double z = 0.3 + 0.2 * layer;
    g += "G1 Z" + std::to_string(z) + " F600\n";
    for (const auto& [name, x0] : {std::pair<std::string, int>{"'part a'", 50}, {"part_b", 140}}) {
      g += "EXCLUDE_OBJECT_START NAME=" + name + "\n";
      g += "G1 X" + std::to_string(x0) + " Y" + std::to_string(x0) + " F9000\n";
      for (int k = 1; k <= 7; ++k) {
        g += "G1 X" + std::to_string(x0 + (k % 2 ? 20 : 0)) + " Y" + std::to_string(x0 + 2 * k) +
             " E0.8 F1800\n";
        if (layer == 1 && x0 == 140 && k == 3) g += "M601\n";  // paused inside B
      }
      g += "EXCLUDE_OBJECT_END NAME=" + name + "\n";
    }
  }
  return g + "G1 X10 Y200 F9000\n";
}

// Moves the planner's own interpreter plans for the lines after the M601, with `exclude` first.
uint64_t moves_after_pause(const std::string& text, const std::string& exclude) {
  planner::test::Rig rig{planner::test::cartesian_config()};
  std::istringstream in(text);
  bool after = false;
  uint64_t start = 0;
  for (std::string l; std::getline(in, l);) {
    if (l == "M601") {
      if (after) continue;  // the second pause
      after = true;
      if (!exclude.empty()) {
        EXPECT_TRUE(rig.run(exclude).ok());
      }
      start = rig.planner.moves_added();
      continue;
    }
    EXPECT_TRUE(rig.run(l).ok()) << l;
  }
  EXPECT_TRUE(after);
  return rig.planner.moves_added() - start;
}

TEST_F(WebJobsVirtual, TheWebExcludesAnObjectOfARunningPrint) {
  const std::string text = two_objects_gcode();
  { std::ofstream(dir_ + "/gcodes/plate.gcode") << text; }
  LineClient api;
  ASSERT_TRUE(api.connect_unix(daemon_->api_socket_path()));
  auto moves_planned = [&] {
    return call(api, "status")["result"]["motion"]["moves_planned"].get<uint64_t>();
  };
  ASSERT_EQ(request(port(), http::verb::post, "/printer/print/start?filename=plate.gcode").status,
            200);
  json s = wait_objects(
      "print_stats&exclude_object",
      [](const json& o) {
        return o["print_stats"]["state"] == "paused" && o["exclude_object"]["objects"].size() == 2;
      },
      30);
  ASSERT_EQ(s["print_stats"]["state"], "paused") << s.dump();
  // print_stats says "paused" as soon as the pause is asked (as Klipper's does); the job is
  // paused once its park is queued and has run. The moves counted below start there (on a
  // loaded machine the park's three moves were once still to come: counted as the resume's).
  auto wait_job_parked = [&] {
    for (int i = 0; i < 200 && call(api, "job.status")["result"]["state"] != "paused"; ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    return call(api, "job.status")["result"]["state"] == "paused";
  };
  ASSERT_TRUE(wait_job_parked());
  ASSERT_EQ(s["exclude_object"]["objects"].size(), 2u) << s.dump();
  EXPECT_EQ(s["exclude_object"]["objects"][0]["name"], "PART A");
  EXPECT_EQ(s["exclude_object"]["objects"][1]["name"], "PART_B");
  EXPECT_TRUE(s["exclude_object"]["excluded_objects"].empty());
  EXPECT_TRUE(s["exclude_object"]["current_object"].is_null());
  // Paused, the job sends nothing and owns nothing: a jog from another client (the API's) takes
  // the print. The web's move is then refused as busy; its exclusion is not (it moves nothing).
  const json jog = call(api, "gcode", {{"script", "G1 X5 F6000"}});
  ASSERT_TRUE(jog.contains("result")) << jog.dump();
  Reply busy = request(port(), http::verb::post, "/printer/gcode/script?script=G1%20X6");
  EXPECT_NE(busy.status, 200) << busy.body.dump();
  EXPECT_NE(busy.body.dump().find("busy"), std::string::npos) << busy.body.dump();
  Reply ex = request(port(), http::verb::post, "/printer/gcode/script",
                     json{{"script", "EXCLUDE_OBJECT NAME=part_b"}}.dump());
  ASSERT_EQ(ex.status, 200) << ex.body.dump();
  s = objects("exclude_object");
  ASSERT_EQ(s["exclude_object"]["excluded_objects"].size(), 1u) << s.dump();
  EXPECT_EQ(s["exclude_object"]["excluded_objects"][0], "PART_B");
  // The jog has moved (the planner may hold a move a moment before it is planned): the moves
  // counted from here are the job's and the file's.
  for (int i = 0; i < 500 && call(api, "status")["result"]["state"] == "busy"; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  ASSERT_NE(call(api, "status")["result"]["state"], "busy");
  const uint64_t before = moves_planned();
  // The client that jogged resumes (the web may not: the print is the API's until it idles).
  const json resumed = call(api, "job.resume");
  ASSERT_TRUE(resumed.contains("result")) << resumed.dump();
  // The second pause, inside B: the job is parked, B is the file's object.
  s = wait_objects(
      "print_stats&exclude_object",
      [](const json& o) { return o["print_stats"]["state"] == "paused"; }, 60);
  ASSERT_EQ(s["print_stats"]["state"], "paused") << s.dump();
  ASSERT_TRUE(wait_job_parked());
  // The first pause came right after the G28, which left X and Y past their limits by the
  // homing's overshoot: the way back went inside the travel, not refused. The message is the
  // file's pause, no error.
  const std::string paused_message = call(api, "job.status")["result"]["message"];
  EXPECT_EQ(paused_message.rfind("paused by M601 in the file (plate.gcode:", 0), 0u)
      << paused_message;
  EXPECT_TRUE(objects("exclude_object")["exclude_object"]["current_object"].is_null());
  ASSERT_EQ(request(port(), http::verb::post, "/printer/print/resume").status, 200);
  s = wait_objects(
      "print_stats", [](const json& o) { return o["print_stats"]["state"] == "complete"; }, 120);
  ASSERT_EQ(s["print_stats"]["state"], "complete") << s.dump();
  const uint64_t planned = moves_planned() - before;
  const uint64_t with_b = moves_after_pause(text, "");
  const uint64_t without_b = moves_after_pause(text, "EXCLUDE_OBJECT NAME=part_b");
  std::printf("moves after the pause: %llu planned; the interpreter: %llu without B, %llu with B\n",
              static_cast<unsigned long long>(planned), static_cast<unsigned long long>(without_b),
              static_cast<unsigned long long>(with_b));
  EXPECT_EQ(with_b - without_b, 24u);
  // The job's own: 3 back after the first pause, 3 to park and 3 back at the second, and up to
  // its three settle dwells (a G4 while the machine still moves is a standstill move, which
  // depends on how far the machine's clock ran ahead of the job; measured: 12). Were the
  // park and the way back skipped inside B, 6 fewer; were B's 12 moves after the second pause
  // not skipped, 12 more.
  EXPECT_GE(planned, without_b + 9);
  EXPECT_LE(planned, without_b + 12);
  // The next print starts with nothing excluded.
  ASSERT_EQ(request(port(), http::verb::post, "/printer/print/start?filename=plate.gcode").status,
            200);
  s = wait_objects(
      "print_stats&exclude_object",
      [](const json& o) {
        return o["print_stats"]["state"] == "paused" && o["exclude_object"]["objects"].size() == 2;
      },
      30);
  EXPECT_TRUE(s["exclude_object"]["excluded_objects"].empty()) << s.dump();
  EXPECT_EQ(s["exclude_object"]["objects"].size(), 2u) << s.dump();
  ASSERT_TRUE(call(api, "job.cancel").contains("result"));
}

// The same kind of plate sliced for a Marlin printer (PrusaSlicer's M486 index form, with its
// name lines): the web lists the objects by their names and excludes object 1 by its name, as
// Mainsail sends it, while the job is paused at the file's M601; resumed, nothing of object 1 is
// planned: as many moves as the planner's own interpreter plans with "M486 P1" (12 fewer than
// with it), plus the job's way back (3 moves) and its settle dwell.
std::string marlin_objects_gcode() {
  std::string g = "G28\nM302 P1\nM83\nM486 T2\n";  // cold extrusion: nothing heats here
  for (int i = 0; i < 2; ++i)
    g += "M486 S" + std::to_string(i) + "\nM486 AShape-Box id:" + std::to_string(i) +
         " copy 0\nM486 S-1\n";
  g += "G1 Z0.3 F600\nG1 X20 Y20 F9000\nM601\n";
  for (int layer = 0; layer < 2; ++layer) {
    g += "G1 Z" + std::to_string(0.3 + 0.2 * layer) + " F600\n";
    for (int i = 0; i < 2; ++i) {
      const int x0 = 50 + 90 * i;
      g += "M486 S" + std::to_string(i) + "\n";
      g += "G1 X" + std::to_string(x0) + " Y" + std::to_string(x0) + " F9000\n";
      for (int k = 1; k <= 5; ++k)
        g += "G1 X" + std::to_string(x0 + (k % 2 ? 20 : 0)) + " Y" + std::to_string(x0 + 2 * k) +
             " E0.8 F1800\n";
      g += "M486 S-1\n";
    }
  }
  return g + "G1 X10 Y200 F9000\n";
}

TEST_F(WebJobsVirtual, TheWebExcludesAMarlinLabelledObjectByItsName) {
  const std::string text = marlin_objects_gcode();
  { std::ofstream(dir_ + "/gcodes/marlin.gcode") << text; }
  LineClient api;
  ASSERT_TRUE(api.connect_unix(daemon_->api_socket_path()));
  auto moves_planned = [&] {
    return call(api, "status")["result"]["motion"]["moves_planned"].get<uint64_t>();
  };
  ASSERT_EQ(request(port(), http::verb::post, "/printer/print/start?filename=marlin.gcode").status,
            200);
  for (int i = 0; i < 400 && call(api, "job.status")["result"]["state"] != "paused"; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  ASSERT_EQ(call(api, "job.status")["result"]["state"], "paused");
  json s = objects("exclude_object");
  ASSERT_EQ(s["exclude_object"]["objects"].size(), 2u) << s.dump();
  EXPECT_EQ(s["exclude_object"]["objects"][0]["name"], "SHAPE-BOX_ID:0_COPY_0");
  EXPECT_EQ(s["exclude_object"]["objects"][1]["name"], "SHAPE-BOX_ID:1_COPY_0");
  Reply ex = request(port(), http::verb::post, "/printer/gcode/script",
                     json{{"script", "EXCLUDE_OBJECT NAME=SHAPE-BOX_ID:1_COPY_0"}}.dump());
  ASSERT_EQ(ex.status, 200) << ex.body.dump();
  s = objects("exclude_object");
  ASSERT_EQ(s["exclude_object"]["excluded_objects"], json::array({"SHAPE-BOX_ID:1_COPY_0"}))
      << s.dump();
  const uint64_t before = moves_planned();
  ASSERT_EQ(request(port(), http::verb::post, "/printer/print/resume").status, 200);
  s = wait_objects(
      "print_stats", [](const json& o) { return o["print_stats"]["state"] == "complete"; }, 120);
  ASSERT_EQ(s["print_stats"]["state"], "complete") << s.dump();
  const uint64_t planned = moves_planned() - before;
  const uint64_t with_1 = moves_after_pause(text, "");
  const uint64_t without_1 = moves_after_pause(text, "M486 P1");
  std::printf(
      "Marlin labels: %llu planned after the pause; the interpreter: %llu without object 1, "
      "%llu with it\n",
      static_cast<unsigned long long>(planned), static_cast<unsigned long long>(without_1),
      static_cast<unsigned long long>(with_1));
  EXPECT_EQ(with_1 - without_1, 12u);
  EXPECT_GE(planned, without_1 + 3);
  EXPECT_LE(planned, without_1 + 4);
  EXPECT_EQ(call(api, "job.status")["result"]["message"], "");
}

// Wall clock: the heaters and the fan's kick-start run on the machine's time.
// A file in a subfolder of gcodes (uploaded with Moonraker's `path` field, as both UIs do in a
// folder) is printed by its relative path; a path out of the folder, or through a hidden folder,
// is refused with the reason and starts nothing.
TEST_F(WebJobsVirtual, AFileInASubfolderPrintsAndEscapesAreRefused) {
  const std::string text =
      read_file(std::string(FEEDLOOP_SOURCE_DIR) + "/examples/gcode/cube20_3layers.gcode");
  const std::string form =
      "--XyZ\r\nContent-Disposition: form-data; name=\"path\"\r\n\r\nparts/small\r\n" +
      multipart("cube.gcode", text);
  Reply up = request(port(), http::verb::post, "/server/files/upload", form,
                     "multipart/form-data; boundary=XyZ");
  ASSERT_EQ(up.status, 201) << up.body.dump();
  ASSERT_EQ(read_file(dir_ + "/gcodes/parts/small/cube.gcode"), text);
  std::ofstream(dir_ + "/outside.gcode") << "G28\n";
  std::filesystem::create_directories(dir_ + "/gcodes/.hidden");
  std::ofstream(dir_ + "/gcodes/.hidden/h.gcode") << "G28\n";
  for (const char* bad : {"../outside.gcode", "parts/../../outside.gcode", ".hidden/h.gcode",
                          "parts//small/cube.gcode", "parts/small/", "parts/small/nope.gcode"}) {
    Reply r =
        request(port(), http::verb::post, std::string("/printer/print/start?filename=") + bad);
    EXPECT_EQ(r.status, 400) << bad << ": " << r.body.dump();
    std::printf("start %-28s -> %d %s\n", bad, r.status,
                r.body["error"]["message"].get<std::string>().c_str());
  }
  EXPECT_EQ(objects("print_stats")["print_stats"]["state"], "standby");
  // An upload that no job could print is refused by the same rules, and no file is kept (it was
  // kept, and then job.start refused it).
  for (const auto& [dir, name] : std::vector<std::pair<std::string, std::string>>{
           {"", ".hidden.gcode"}, {"sub//x", "x.gcode"}, {"", "notes.txt"}, {".h", "y.gcode"}}) {
    std::string bad_form = multipart(name, "G28\n");
    if (!dir.empty())
      bad_form = "--XyZ\r\nContent-Disposition: form-data; name=\"path\"\r\n\r\n" + dir + "\r\n" +
                 bad_form;
    Reply r = request(port(), http::verb::post, "/server/files/upload", bad_form,
                      "multipart/form-data; boundary=XyZ");
    EXPECT_EQ(r.status, 400) << dir << "/" << name << ": " << r.body.dump();
    std::printf("upload %s/%s -> %d %s\n", dir.c_str(), name.c_str(), r.status,
                r.body["error"]["message"].get<std::string>().c_str());
    EXPECT_FALSE(
        std::filesystem::exists(dir_ + "/gcodes/" + (dir.empty() ? "" : dir + "/") + name));
  }
  // The job folder's own check (M23, M32, job.start take the same path): '..' is refused there too.
  for (const char* bad : {"../outside.gcode", "parts/../../outside.gcode", "/abs.gcode",
                          "parts\\cube.gcode", "parts/cube.txt"})
    EXPECT_FALSE(daemon::JobFiles::validate_path(bad).ok()) << bad;
  EXPECT_TRUE(daemon::JobFiles::validate_path("parts/small/cube.gcode").ok());

  Reply start =
      request(port(), http::verb::post, "/printer/print/start?filename=parts/small/cube.gcode");
  ASSERT_EQ(start.status, 200) << start.body.dump();
  json s = wait_objects(
      "print_stats&virtual_sdcard",
      [](const json& o) { return o["print_stats"]["state"] != "printing"; }, 300);
  ASSERT_EQ(s["print_stats"]["state"], "complete") << s.dump();
  EXPECT_EQ(s["print_stats"]["filename"], "parts/small/cube.gcode");
  EXPECT_EQ(s["virtual_sdcard"]["file_path"], dir_ + "/gcodes/parts/small/cube.gcode");
  EXPECT_EQ(s["virtual_sdcard"]["file_position"], text.size());
  EXPECT_NEAR(s["print_stats"]["filament_used"].get<double>(), filament_of(text), 1e-6);
  Reply hist = request(port(), http::verb::get, "/server/history/list?limit=1");
  ASSERT_EQ(hist.status, 200);
  EXPECT_EQ(hist.body["result"]["jobs"][0]["filename"], "parts/small/cube.gcode");
  EXPECT_EQ(hist.body["result"]["jobs"][0]["status"], "completed");
}

// A slicer's "send to printer" (PrusaSlicer, SuperSlicer, OrcaSlicer set up as an OctoPrint host;
// Cura's OctoPrint plugin), as Moonraker's octoprint_compat answers it: the connection test, the
// upload into a folder with print=true, the job's state and progress, G-code, cancel.
TEST_F(WebJobsVirtual, ASlicerSendsAPrintThroughOctoPrintsApi) {
  Reply version = request(port(), http::verb::get, "/api/version");
  ASSERT_EQ(version.status, 200) << version.body.dump();
  EXPECT_EQ(version.body["text"].get<std::string>().rfind("OctoPrint", 0),
            0u);  // PrusaSlicer's check
  EXPECT_EQ(request(port(), http::verb::get, "/api/printer").body["state"]["text"], "Operational");

  const std::string text =
      read_file(std::string(FEEDLOOP_SOURCE_DIR) + "/examples/gcode/cube20_3layers.gcode");
  const std::string form =
      "--XyZ\r\nContent-Disposition: form-data; name=\"print\"\r\n\r\ntrue\r\n"
      "--XyZ\r\nContent-Disposition: form-data; name=\"path\"\r\n\r\nfrom_slicer\r\n" +
      multipart("cube.gcode", text);
  Reply up = request(port(), http::verb::post, "/api/files/local", form,
                     "multipart/form-data; boundary=XyZ");
  ASSERT_EQ(up.status, 201) << up.body.dump();
  EXPECT_EQ(up.body["files"]["local"]["path"], "from_slicer/cube.gcode");
  EXPECT_EQ(up.body["effectivePrint"], true);
  EXPECT_EQ(read_file(dir_ + "/gcodes/from_slicer/cube.gcode"), text);

  Reply job = request(port(), http::verb::get, "/api/job");
  ASSERT_EQ(job.status, 200);
  EXPECT_EQ(job.body["job"]["file"]["name"], "from_slicer/cube.gcode");
  EXPECT_EQ(job.body["job"]["file"]["size"], text.size());
  json done = wait_objects(
      "print_stats", [](const json& o) { return o["print_stats"]["state"] != "printing"; }, 300);
  EXPECT_EQ(done["print_stats"]["state"], "complete") << done.dump();
  job = request(port(), http::verb::get, "/api/job");
  EXPECT_EQ(job.body["state"], "Operational") << job.body.dump();
  EXPECT_DOUBLE_EQ(job.body["progress"]["completion"].get<double>(), 100.0);

  // Started again from the upload, then cancelled through /api/job.
  Reply again = request(port(), http::verb::post, "/api/files/local", form,
                        "multipart/form-data; boundary=XyZ");
  ASSERT_EQ(again.status, 201) << again.body.dump();
  EXPECT_EQ(request(port(), http::verb::get, "/api/job").body["state"], "Printing");
  EXPECT_EQ(request(port(), http::verb::post, "/api/job", R"({"command": "cancel"})").status, 204);
  json cancelled = wait_objects(
      "print_stats", [](const json& o) { return o["print_stats"]["state"] == "cancelled"; }, 60);
  EXPECT_EQ(cancelled["print_stats"]["state"], "cancelled") << cancelled.dump();
  EXPECT_EQ(request(port(), http::verb::post, "/api/job", R"({"command": "cancel"})").status, 409);

  // G-code, once the job is over: 204 once it ran; a line the machine refuses is 409 with its
  // reason.
  Reply cmd = request(port(), http::verb::post, "/api/printer/command",
                      R"({"commands": ["G28", "G1 X12 Y7 F3000"]})");
  EXPECT_EQ(cmd.status, 204);
  json pos = objects("toolhead")["toolhead"]["position"];
  EXPECT_NEAR(pos[0].get<double>(), 12.0, 1e-9) << pos.dump();
  EXPECT_NEAR(pos[1].get<double>(), 7.0, 1e-9) << pos.dump();
  EXPECT_EQ(request(port(), http::verb::post, "/api/printer/command", R"({"command": "G1 X9999"})")
                .status,
            409);
  EXPECT_EQ(request(port(), http::verb::post, "/api/printer/command", R"({"commands": 3})").status,
            400);

  // What no job could print, a root the slicer may not choose, and routes OctoPrint has and
  // feedloop does not.
  Reply hidden = request(port(), http::verb::post, "/api/files/local",
                         multipart(".hidden.gcode", "G28\n"), "multipart/form-data; boundary=XyZ");
  EXPECT_EQ(hidden.status, 400) << hidden.body.dump();
  const std::string config_form =
      "--XyZ\r\nContent-Disposition: form-data; name=\"root\"\r\n\r\nconfig\r\n"
      "--XyZ\r\nContent-Disposition: form-data; name=\"file\"; filename=\"x.gcode\"\r\n\r\n"
      "G28\n\r\n--XyZ--\r\n";
  EXPECT_EQ(request(port(), http::verb::post, "/api/files/local", config_form,
                    "multipart/form-data; boundary=XyZ")
                .status,
            201);
  EXPECT_TRUE(std::filesystem::exists(dir_ + "/gcodes/x.gcode"));
  EXPECT_EQ(request(port(), http::verb::get, "/api/timelapse").status, 404);
}

// Moonraker's HTTP form of a G-code script (POST /printer/gcode/script, the script in the query or
// a JSON body): answered when the machine has run it. The reply comes later than the request's
// handler returns, and the connection was closed first (an empty reply to every script). An M112
// there stops the machine, and M999 brings it back.
TEST_F(WebJobs, AGcodeScriptOverHttpIsAnsweredWhenItHasRun) {
  Reply home = request(port(), http::verb::post, "/printer/gcode/script?script=G28");
  EXPECT_EQ(home.status, 200);
  EXPECT_EQ(home.body["result"], "ok") << home.body.dump();
  Reply move = request(port(), http::verb::post, "/printer/gcode/script",
                       json{{"script", "G1 X10 F6000\nM400"}}.dump());
  EXPECT_EQ(move.status, 200);
  EXPECT_EQ(move.body["result"], "ok") << move.body.dump();
  EXPECT_DOUBLE_EQ(objects("toolhead")["toolhead"]["position"][0].get<double>(), 10.0);
  Reply stop = request(port(), http::verb::post, "/printer/gcode/script?script=M112");
  EXPECT_EQ(stop.status, 200);
  EXPECT_EQ(request(port(), http::verb::get, "/server/info").body["result"]["klippy_state"],
            "shutdown");
  Reply restart = request(port(), http::verb::post, "/printer/gcode/script?script=M999");
  EXPECT_EQ(restart.status, 200) << restart.body.dump();
  EXPECT_EQ(request(port(), http::verb::get, "/server/info").body["result"]["klippy_state"],
            "ready");
}

// Mainsail's speed and flow sliders send M220 / M221 and show gcode_move's speed_factor and
// extrude_factor; its move buttons read absolute_coordinates, its status panel the requested
// speed (speed / 60 x speed_factor). They were constants (1, 1, true, 0): a slider set to 150 %
// snapped back to 100 % while the print ran at 150 %, and the requested speed read 0 mm/s.
TEST_F(WebJobs, TheSpeedAndFlowSlidersShowWhatM220AndM221Set) {
  Reply set = request(port(), http::verb::post, "/printer/gcode/script",
                      json{{"script", "G1 X1 F1200\nM220 S150\nM221 S90\nG91"}}.dump());
  ASSERT_EQ(set.status, 200) << set.body.dump();
  json g = wait_objects(
      "gcode_move",
      [](const json& s) { return s["gcode_move"]["speed_factor"].get<double>() != 1.0; }, 10);
  EXPECT_DOUBLE_EQ(g["gcode_move"]["speed_factor"].get<double>(), 1.5) << g.dump();
  EXPECT_DOUBLE_EQ(g["gcode_move"]["extrude_factor"].get<double>(), 0.9) << g.dump();
  EXPECT_EQ(g["gcode_move"]["absolute_coordinates"], false) << g.dump();
  EXPECT_EQ(g["gcode_move"]["absolute_extrude"], false) << g.dump();  // E follows G91
  EXPECT_DOUBLE_EQ(g["gcode_move"]["speed"].get<double>(), 1200.0) << g.dump();  // F, mm/min
  set = request(port(), http::verb::post, "/printer/gcode/script",
                json{{"script", "G90\nM83\nM220 S100"}}.dump());
  ASSERT_EQ(set.status, 200) << set.body.dump();
  g = wait_objects(
      "gcode_move",
      [](const json& s) { return s["gcode_move"]["speed_factor"].get<double>() == 1.0; }, 10);
  EXPECT_DOUBLE_EQ(g["gcode_move"]["speed_factor"].get<double>(), 1.0) << g.dump();
  EXPECT_EQ(g["gcode_move"]["absolute_coordinates"], true) << g.dump();
  EXPECT_EQ(g["gcode_move"]["absolute_extrude"], false) << g.dump();  // M83
}

TEST_F(WebJobs, FanPowerConsoleEchoAndAStreamedPrint) {
  LineClient marlin;
  ASSERT_TRUE(marlin.connect_unix(daemon_->socket_path()));
  ASSERT_TRUE(marlin.send_line("M106 S128"));
  ASSERT_TRUE(marlin.read_until("ok", 5000));
  json s = wait_objects(
      "fan",
      [](const json& o) {
        return std::abs(o["fan"]["speed"].get<double>() - 128.0 / 255.0) < 1e-3;
      },
      5);
  EXPECT_NEAR(s["fan"]["speed"].get<double>(), 128.0 / 255.0, 1e-3) << s.dump();
  ASSERT_TRUE(marlin.send_line("M104 S200"));
  ASSERT_TRUE(marlin.read_until("ok", 5000));
  s = wait_objects(
      "extruder&heater_bed",
      [](const json& o) { return o["extruder"]["power"].get<double>() > 0.5; }, 5);
  EXPECT_GT(s["extruder"]["power"].get<double>(), 0.5) << s.dump();  // full power far below 200
  EXPECT_LE(s["extruder"]["power"].get<double>(), 1.0);
  EXPECT_DOUBLE_EQ(s["heater_bed"]["power"].get<double>(), 0.0);
  ASSERT_TRUE(marlin.send_line(numbered(1, "M104 S0")));  // with a line number and checksum
  ASSERT_TRUE(marlin.read_until("ok", 5000));
  ASSERT_TRUE(marlin.send_line("M107"));
  ASSERT_TRUE(marlin.read_until("ok", 5000));
  s = wait_objects(
      "fan&extruder", [](const json& o) { return o["fan"]["speed"].get<double>() == 0.0; }, 5);
  EXPECT_DOUBLE_EQ(s["fan"]["speed"].get<double>(), 0.0);

  // The console shows another channel's lines (N and checksum taken off), not its moves.
  ASSERT_TRUE(marlin.send_line("G1 X5 F3000"));
  ASSERT_TRUE(marlin.read_until("ok", 5000));
  Reply store = request(port(), http::verb::get, "/server/gcode_store?count=50");
  ASSERT_EQ(store.status, 200);
  std::vector<std::string> lines;
  for (const json& e : store.body["result"]["gcode_store"]) lines.push_back(e["message"]);
  auto has = [&](const std::string& suffix) {
    for (const std::string& l : lines)
      if (l.size() >= suffix.size() &&
          l.compare(l.size() - suffix.size(), suffix.size(), suffix) == 0 &&
          l.rfind("socket", 0) == 0)
        return true;
    return false;
  };
  EXPECT_TRUE(has(": M106 S128")) << store.body.dump();
  EXPECT_TRUE(has(": M104 S0")) << store.body.dump();
  EXPECT_TRUE(has(": M107")) << store.body.dump();
  EXPECT_FALSE(has(": G1 X5 F3000")) << store.body.dump();

  // A print streamed over the socket: print_stats says printing (no file) while the client owns
  // the print, and standby once it has gone.
  s = objects("print_stats");
  EXPECT_EQ(s["print_stats"]["state"], "printing") << s.dump();
  EXPECT_EQ(s["print_stats"]["filename"], "");
  EXPECT_NE(s["print_stats"]["message"].get<std::string>().find("streamed by socket"),
            std::string::npos)
      << s.dump();
  for (int i = 0; i < 20; ++i) {
    ASSERT_TRUE(marlin.send_line("G1 X" + std::to_string(10 + i) + " Y10 F6000"));
    ASSERT_TRUE(marlin.read_until("ok", 5000));
  }
  s = objects("print_stats");
  EXPECT_EQ(s["print_stats"]["state"], "printing");
  EXPECT_GT(s["print_stats"]["print_duration"].get<double>(), 0.0);
  marlin.close();
  s = wait_objects(
      "print_stats", [](const json& o) { return o["print_stats"]["state"] != "printing"; }, 5);
  EXPECT_EQ(s["print_stats"]["state"], "standby") << s.dump();
  // No history entry for a stream (Moonraker records virtual_sdcard prints only).
  Reply hist = request(port(), http::verb::get, "/server/history/list");
  EXPECT_EQ(hist.body["result"]["jobs"].size(), 0u) << hist.body.dump();
}

// A host streaming a print (OctoPrint) sends Cura's M0 or a slicer's M600: the machine stops for
// the user. The web shows the print paused with the stop's text, and its resume button answers
// the stop as the host's M108 would; so does an M108 typed in the web's console.
TEST_F(WebJobs, TheWebResumesAStreamingHostsStopForTheUser) {
  LineClient host;
  ASSERT_TRUE(host.connect_unix(daemon_->socket_path()));
  for (const char* line : {"G28", "G1 X10 Y10 F6000"}) {
    ASSERT_TRUE(host.send_line(line));
    ASSERT_EQ(host.read_until("ok", 20000), "ok") << line;
  }
  // Nothing to resume yet: Klipper's answer.
  Reply early = request(port(), http::verb::post, "/printer/print/resume");
  EXPECT_NE(early.status, 200) << early.body.dump();
  ASSERT_TRUE(host.send_line("M0 Check the first layer"));
  ASSERT_EQ(host.read_until("//action:prompt_show", 20000), "//action:prompt_show");
  ASSERT_TRUE(host.send_line("G1 X20"));
  json s = objects("print_stats&pause_resume");
  EXPECT_EQ(s["print_stats"]["state"], "paused") << s.dump();
  EXPECT_NE(s["print_stats"]["message"].get<std::string>().find("streamed by socket"),
            std::string::npos)
      << s.dump();
  EXPECT_EQ(s["pause_resume"]["is_paused"], true) << s.dump();
  Reply resume = request(port(), http::verb::post, "/printer/print/resume");
  EXPECT_EQ(resume.status, 200) << resume.body.dump();
  EXPECT_EQ(host.read_until("//action:prompt_end", 5000), "//action:prompt_end");
  EXPECT_EQ(host.read_line(5000), "ok");          // M0's
  EXPECT_EQ(host.read_until("ok", 20000), "ok");  // G1 X20's
  ASSERT_TRUE(host.send_line("M400"));
  ASSERT_EQ(host.read_until("ok", 20000), "ok");
  EXPECT_DOUBLE_EQ(objects("toolhead")["toolhead"]["position"][0].get<double>(), 20.0);
  s = objects("print_stats");
  EXPECT_EQ(s["print_stats"]["state"], "printing") << s.dump();
  // The console's M108 answers the next stop.
  ASSERT_TRUE(host.send_line("M0"));
  ASSERT_EQ(host.read_until("//action:prompt_show", 20000), "//action:prompt_show");
  Reply m108 = request(port(), http::verb::post, "/printer/gcode/script?script=M108");
  EXPECT_EQ(m108.status, 200) << m108.body.dump();
  EXPECT_EQ(host.read_until("//action:prompt_end", 5000), "//action:prompt_end");
  EXPECT_EQ(host.read_line(5000), "ok");
}

TEST_F(WebJobs, FeedloopsPageGetsTheNewestCalibrationReport) {
  Reply none = request(port(), http::verb::get, "/server/feedloop/calibration_report");
  ASSERT_EQ(none.status, 200);
  EXPECT_FALSE(none.body["result"]["found"].get<bool>());
  EXPECT_NE(none.body["result"]["message"].get<std::string>().find("no calibration report yet"),
            std::string::npos);
  namespace fs = std::filesystem;
  fs::create_directories(dir_ + "/ident/old");
  fs::create_directories(dir_ + "/ident/new");
  std::ofstream(dir_ + "/ident/old/report.json")
      << R"({"axis":"y","baseline":{"model":"m","rms_um":9},"effects":[],"augmented":{"model":"m","rms_um":9}})";
  fs::last_write_time(dir_ + "/ident/old/report.json",
                      fs::file_time_type::clock::now() - std::chrono::hours(1));
  std::ofstream(dir_ + "/ident/new/report.json")
      << R"({"axis":"x","baseline":{"model":"thesis Eq. 13","rms_um":12.3},)"
      << R"("effects":[{"name":"periodic_position","params":{"period_mm":33.9,"amplitude_um":25.0}}],)"
      << R"("augmented":{"model":"thesis Eq. 13 + periodic_position","rms_um":3.1}})";
  std::ofstream(dir_ + "/ident/new/report.md") << "# Identification report\n";
  Reply r = request(port(), http::verb::get, "/server/feedloop/calibration_report");
  ASSERT_EQ(r.status, 200);
  const json& c = r.body["result"];
  ASSERT_TRUE(c["found"].get<bool>()) << c.dump();
  EXPECT_EQ(c["path"], dir_ + "/ident/new/report.json");
  EXPECT_EQ(c["report"]["axis"], "x");
  EXPECT_EQ(c["report"]["effects"][0]["name"], "periodic_position");
  EXPECT_DOUBLE_EQ(c["report"]["augmented"]["rms_um"].get<double>(), 3.1);
  EXPECT_EQ(c["markdown"], "# Identification report\n");
  // A newer file that is not JSON: named, with the parser's message.
  fs::create_directories(dir_ + "/ident/broken");
  std::ofstream(dir_ + "/ident/broken/report.json") << "{\"axis\": ";
  r = request(port(), http::verb::get, "/server/feedloop/calibration_report");
  EXPECT_FALSE(r.body["result"]["found"].get<bool>());
  const std::string msg = r.body["result"]["message"];
  EXPECT_NE(msg.find(dir_ + "/ident/broken/report.json: not JSON"), std::string::npos) << msg;
}

}  // namespace
}  // namespace feedloop::testing
