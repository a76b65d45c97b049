// The Moonraker API without a network (web/moonraker_api.hpp) and its parts: JSON-RPC as the UIs
// send it (ids from 0, no params, batches), errors, subscriptions sending only what changed,
// PAUSE/RESUME macros, files, the SQLite database with dotted keys, multipart uploads, access.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>

#include "tests/web/fake_printer.hpp"
#include "web/access.hpp"
#include "web/database.hpp"
#include "web/file_store.hpp"
#include "web/moonraker_api.hpp"
#include "web/multipart.hpp"

namespace feedloop::web {
namespace {

using nlohmann::json;

struct Fixture {
  Fixture() {
    dir = std::filesystem::temp_directory_path() /
          ("web_api_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    std::filesystem::remove_all(dir);
    files = std::make_unique<FileStore>(*FileStore::open(dir.string()));
    db = Database::open(":memory:").value();
    api = std::make_unique<MoonrakerApi>(printer, *files, *db, MoonrakerApi::Options{});
    conn = api->open_connection([this](std::shared_ptr<const std::string> t) {
      sent.push_back(json::parse(*t));
      return true;
    });
  }
  ~Fixture() { std::filesystem::remove_all(dir); }
  // Sends one message; returns the replies (not the notifications) it produced.
  std::vector<json> call(const std::string& text) {
    const size_t before = sent.size();
    api->on_message(conn, text);
    std::vector<json> out;
    for (size_t i = before; i < sent.size(); ++i)
      if (sent[i].is_array() || !sent[i].contains("method")) out.push_back(sent[i]);
    return out;
  }
  json result(const std::string& method, const json& params = json::object()) {
    auto r =
        call(json{{"jsonrpc", "2.0"}, {"method", method}, {"params", params}, {"id", 5}}.dump());
    EXPECT_EQ(r.size(), 1u);
    EXPECT_TRUE(r.at(0).contains("result")) << r.at(0).dump();
    return r.at(0)["result"];
  }
  std::vector<json> notifications(const std::string& method) const {
    std::vector<json> out;
    for (const json& j : sent)
      if (j.is_object() && j.value("method", "") == method) out.push_back(j);
    return out;
  }
  static inline int counter = 0;
  std::filesystem::path dir;
  testing::FakePrinter printer;
  std::unique_ptr<FileStore> files;
  std::unique_ptr<Database> db;
  std::unique_ptr<MoonrakerApi> api;
  uint64_t conn = 0;
  std::vector<json> sent;
};

TEST(WebApi, IdZeroAndNoParamsAreRequestsAndGetOneReplyEach) {
  Fixture f;
  auto r = f.call(
      R"({"jsonrpc":"2.0","method":"server.connection.identify","params":{"client_name":"mainsail"},"id":0})");
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0]["id"], 0);
  EXPECT_EQ(r[0]["result"]["connection_id"], f.conn);
  r = f.call(R"({"jsonrpc":"2.0","method":"printer.objects.list","id":1})");
  ASSERT_EQ(r.size(), 1u);
  const json names = r[0]["result"]["objects"];
  for (const char* o :
       {"toolhead", "gcode_move", "print_stats", "virtual_sdcard", "heaters", "extruder",
        "heater_bed", "fan", "webhooks", "idle_timeout", "motion_report", "system_stats",
        "feedloop_servo", "feedloop_links", "feedloop_tracking"})
    EXPECT_NE(std::find(names.begin(), names.end(), o), names.end()) << o;
  // A notification (no id) gets no reply.
  EXPECT_TRUE(f.call(R"({"jsonrpc":"2.0","method":"server.info"})").empty());
}

TEST(WebApi, ErrorsAreWellFormed) {
  Fixture f;
  auto r = f.call(R"({"jsonrpc":"2.0","method":"server.spoolman.get_spool_id","id":"a"})");
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0]["error"]["code"], -32601);
  EXPECT_EQ(r[0]["id"], "a");
  r = f.call("{not json");
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0]["error"]["code"], -32700);
  r = f.call(R"({"jsonrpc":"2.0","method":"server.files.metadata","params":{},"id":3})");
  EXPECT_EQ(r[0]["error"]["code"], 400);
  EXPECT_EQ(r[0]["error"]["message"], "No data for argument: filename");
  r = f.call(
      R"({"jsonrpc":"2.0","method":"server.files.metadata","params":{"filename":"../../etc/passwd"},"id":4})");
  EXPECT_EQ(r[0]["error"]["code"], 400);
  EXPECT_NE(r[0]["error"]["message"].get<std::string>().find("'..'"), std::string::npos);
  r = f.call(
      R"({"jsonrpc":"2.0","method":"server.database.get_item","params":{"namespace":"fluidd"},"id":6})");
  EXPECT_EQ(r[0]["error"]["code"], 404);
  r = f.call(R"({"jsonrpc":"2.0","method":"printer.objects.query","params":[1,2],"id":7})");
  EXPECT_EQ(r[0]["error"]["code"], -32602);
}

TEST(WebApi, BatchesAnswerWithOneArray) {
  Fixture f;
  auto r = f.call(
      R"([{"jsonrpc":"2.0","method":"server.info","id":1},{"jsonrpc":"2.0","method":"nope","id":2},
                      {"jsonrpc":"2.0","method":"printer.info","id":3}])");
  ASSERT_EQ(r.size(), 1u);
  ASSERT_TRUE(r[0].is_array());
  ASSERT_EQ(r[0].size(), 3u);
  EXPECT_EQ(r[0][0]["result"]["klippy_state"], "ready");
  EXPECT_EQ(r[0][1]["error"]["code"], -32601);
  EXPECT_EQ(r[0][2]["result"]["state"], "ready");
}

TEST(WebApi, SubscriptionSendsOnlyChangedFields) {
  Fixture f;
  const json sub = f.result("printer.objects.subscribe",
                            {{"objects", {{"extruder", nullptr}, {"toolhead", {"position"}}}}});
  EXPECT_EQ(sub["status"]["extruder"]["temperature"], 0.0);
  EXPECT_EQ(sub["status"]["toolhead"].size(), 1u);
  f.api->tick(1.0);
  EXPECT_TRUE(f.notifications("notify_status_update").empty());  // nothing changed
  f.printer.status.hotend_c = 42.5;
  f.printer.status.pos_mm[0] = 10.0;
  f.api->tick(1.3);
  auto n = f.notifications("notify_status_update");
  ASSERT_EQ(n.size(), 1u);
  const json diff = n[0]["params"][0];
  EXPECT_EQ(diff["extruder"].size(), 1u) << diff.dump();  // only the temperature changed
  EXPECT_EQ(diff["extruder"]["temperature"], 42.5);
  EXPECT_EQ(diff["toolhead"]["position"][0], 10.0);
  EXPECT_EQ(n[0]["params"][1], 1.3);
  // A proc_stat update every second keeps Mainsail's 10 s watchdog fed.
  f.api->tick(2.1);
  EXPECT_GE(f.notifications("notify_proc_stat_update").size(), 2u);
}

TEST(WebApi, GcodeScriptRunsMacrosAndBroadcastsResponses) {
  Fixture f;
  const std::string path = (f.dir / "gcodes" / "a.gcode").string();
  ASSERT_TRUE(f.files->write("gcodes", "a.gcode", "G1 X1\n"));
  EXPECT_EQ(f.result("printer.gcode.script", {{"script", "SDCARD_PRINT_FILE FILENAME=a.gcode"}}),
            "ok");
  EXPECT_EQ(f.printer.job.state, JobState::printing);
  EXPECT_EQ(f.printer.last_job_path, path);
  EXPECT_EQ(f.result("printer.gcode.script", {{"script", "PAUSE"}}), "ok");
  EXPECT_EQ(f.printer.job.state, JobState::paused);
  EXPECT_EQ(f.result("printer.gcode.script", {{"script", "RESUME"}}), "ok");
  EXPECT_EQ(f.printer.job.state, JobState::printing);
  f.printer.status.hotend_c = 200.25;
  EXPECT_EQ(f.result("printer.gcode.script", {{"script", "M104 S210\nM105"}}), "ok");
  EXPECT_EQ(f.printer.status.hotend_target_c, 210.0);
  auto g = f.notifications("notify_gcode_response");
  ASSERT_FALSE(g.empty());
  EXPECT_EQ(g.back()["params"][0].get<std::string>().rfind("T:200.25", 0), 0u) << g.back().dump();
  auto r = f.call(
      R"({"jsonrpc":"2.0","method":"printer.gcode.script","params":{"script":"BAD X"},"id":9})");
  EXPECT_EQ(r[0]["error"]["code"], 400);
  EXPECT_EQ(f.notifications("notify_gcode_response").back()["params"][0],
            "!! unknown command BAD X");
  r = f.call(R"({"jsonrpc":"2.0","method":"printer.print.resume","id":10})");
  EXPECT_EQ(r[0]["error"]["message"], "Print is not paused, resume aborted");
}

TEST(WebApi, HistoryRecordsAJobFromStartToEnd) {
  Fixture f;
  ASSERT_TRUE(f.files->write("gcodes", "b.gcode",
                             "; generated by PrusaSlicer 2.7.1\nG1 Z0.2\nG1 Z0.4\n; estimated "
                             "printing time (normal mode) = 1h 2m 3s\n"));
  EXPECT_EQ(f.result("printer.print.start", {{"filename", "b.gcode"}}), "ok");
  f.api->tick(1.0);
  f.printer.job.state = JobState::complete;
  f.printer.job.print_duration_s = 12.5;
  f.api->tick(2.0);
  const json h = f.result("server.history.list", {{"limit", 10}});
  ASSERT_EQ(h["count"], 1);
  EXPECT_EQ(h["jobs"][0]["status"], "completed");
  EXPECT_EQ(h["jobs"][0]["print_duration"], 12.5);
  EXPECT_EQ(h["jobs"][0]["metadata"]["estimated_time"], 3723.0);
  EXPECT_EQ(h["jobs"][0]["metadata"]["object_height"], 0.4);
  EXPECT_EQ(h["jobs"][0]["metadata"]["slicer"], "PrusaSlicer");
  EXPECT_EQ(f.result("server.history.totals")["job_totals"]["total_print_time"], 12.5);
  EXPECT_EQ(f.notifications("notify_history_changed").size(), 2u);
}

// Heater power and fans from the thermal loop's status: the first hotend is `extruder`, the first
// bed `heater_bed`, the first part fan `fan`, a heater fan `heater_fan <name>`.
TEST(WebApi, HeaterPowerAndFansComeFromTheMachineStatus) {
  Fixture f;
  engine::MachineStatus& s = f.printer.status;
  s.num_heaters = 2;
  std::snprintf(s.heaters[0].name, sizeof s.heaters[0].name, "bed");
  s.heaters[0].marlin = 'B';
  s.heaters[0].power = 0.25;
  std::snprintf(s.heaters[1].name, sizeof s.heaters[1].name, "extruder");
  s.heaters[1].marlin = 'T';
  s.heaters[1].power = 0.75;
  s.num_fans = 2;
  std::snprintf(s.fans[0].name, sizeof s.fans[0].name, "hotend_fan");
  s.fans[0].part = false;
  s.fans[0].speed = s.fans[0].requested = 1.0;
  std::snprintf(s.fans[1].name, sizeof s.fans[1].name, "part");
  s.fans[1].speed = 1.0;  // kick-start: full power for a moment
  s.fans[1].requested = 128.0 / 255.0;
  const json o = f.api->all_objects();
  EXPECT_DOUBLE_EQ(o["extruder"]["power"].get<double>(), 0.75);
  EXPECT_DOUBLE_EQ(o["heater_bed"]["power"].get<double>(), 0.25);
  EXPECT_DOUBLE_EQ(o["fan"]["speed"].get<double>(), 128.0 / 255.0);
  EXPECT_DOUBLE_EQ(o["heater_fan hotend_fan"]["speed"].get<double>(), 1.0);
  const json list = f.result("printer.objects.list")["objects"];
  EXPECT_NE(std::find(list.begin(), list.end(), "heater_fan hotend_fan"), list.end())
      << list.dump();
}

// A print a client streams (printing, no file) is not a history job, as Moonraker records only
// virtual_sdcard prints; the gcodes root may be another folder (the daemon's job folder).
TEST(WebApi, AStreamedPrintIsNoHistoryJobAndTheGcodesRootMayBeElsewhere) {
  Fixture f;
  f.printer.job.state = JobState::printing;  // streamed: no filename
  f.api->tick(1.0);
  f.printer.job.state = JobState::standby;
  f.api->tick(2.0);
  EXPECT_EQ(f.result("server.history.list")["count"], 0);
  const auto jobs = f.dir / "jobs";
  auto store = FileStore::open((f.dir / "files").string(), jobs.string());
  ASSERT_TRUE(store.ok());
  ASSERT_TRUE(store->write("gcodes", "a.gcode", "G28\n"));
  EXPECT_TRUE(std::filesystem::exists(jobs / "a.gcode"));
  EXPECT_EQ(*store->resolve("gcodes", "a.gcode"), (jobs / "a.gcode").string());
  EXPECT_EQ(*store->resolve("config", "x.cfg"), (f.dir / "files" / "config" / "x.cfg").string());
  EXPECT_EQ(store->list("gcodes")->size(), 1u);
}

TEST(WebDatabase, DottedKeysNestAndPersist) {
  const std::string path = (std::filesystem::temp_directory_path() /
                            ("web_db_" + std::to_string(::getpid()) + ".sqlite"))
                               .string();
  std::filesystem::remove(path);
  {
    auto db = Database::open(path).value();
    ASSERT_TRUE(db->post("mainsail", "gcodeViewer.klipperCache.kinematics", "cartesian"));
    ASSERT_TRUE(db->post("mainsail", "gcodeViewer.klipperCache.axis_maximum",
                         json::array({200, 200, 180})));
    ASSERT_TRUE(db->post("mainsail", "initVersion", "2.18.2"));
  }
  auto db = Database::open(path).value();
  EXPECT_EQ(db->namespaces(), std::vector<std::string>{"mainsail"});
  EXPECT_EQ(*db->get("mainsail", "gcodeViewer.klipperCache.kinematics"), "cartesian");
  const json all = *db->get("mainsail", "");
  EXPECT_EQ(all["gcodeViewer"]["klipperCache"]["axis_maximum"][2], 180);
  EXPECT_EQ(all["initVersion"], "2.18.2");
  EXPECT_EQ(*db->remove("mainsail", "gcodeViewer.klipperCache.kinematics"), "cartesian");
  EXPECT_FALSE(db->get("mainsail", "gcodeViewer.klipperCache.kinematics"));
  EXPECT_FALSE(db->post("mainsail", "a..b", 1));
  std::filesystem::remove(path);
}

TEST(WebMultipart, ParsesTheUploadAndRefusesBrokenBodies) {
  const std::string body =
      "--XyZ\r\nContent-Disposition: form-data; name=\"root\"\r\n\r\ngcodes\r\n"
      "--XyZ\r\nContent-Disposition: form-data; name=\"file\"; filename=\"cube.gcode\"\r\n"
      "Content-Type: application/octet-stream\r\n\r\nG28\r\nG1 X1\r\n--XyZ--\r\n";
  auto f = parse_multipart("multipart/form-data; boundary=XyZ", body);
  ASSERT_TRUE(f) << f.error().message;
  EXPECT_EQ(f->fields.at("root"), "gcodes");
  EXPECT_EQ(f->file_name, "cube.gcode");
  EXPECT_EQ(f->file, "G28\r\nG1 X1");
  EXPECT_FALSE(parse_multipart("multipart/form-data", body));
  EXPECT_FALSE(parse_multipart("multipart/form-data; boundary=XyZ", body.substr(0, 60)));
  EXPECT_FALSE(parse_multipart("text/plain", body));
}

TEST(WebAccess, TrustedRangesAndApiKey) {
  namespace ip = boost::asio::ip;
  auto p = AccessPolicy::create({"192.168.1.0/24", "fd00::/8"}, "secret");
  ASSERT_TRUE(p);
  EXPECT_TRUE(p->allowed(ip::make_address("127.0.0.1"), ""));
  EXPECT_TRUE(p->allowed(ip::make_address("192.168.1.77"), ""));
  EXPECT_FALSE(p->allowed(ip::make_address("192.168.2.1"), ""));
  EXPECT_TRUE(p->allowed(ip::make_address("192.168.2.1"), "secret"));
  EXPECT_FALSE(p->allowed(ip::make_address("192.168.2.1"), "wrong"));
  EXPECT_TRUE(p->allowed(ip::make_address("fd12::1"), ""));
  EXPECT_TRUE(p->allowed(ip::make_address("::ffff:192.168.1.5"), ""));
  EXPECT_FALSE(AccessPolicy::create({"300.1.1.1/8"}, ""));
}

TEST(WebFiles, ListsDirectoriesAndRefusesEscapes) {
  Fixture f;
  ASSERT_TRUE(f.files->write("gcodes", "sub/x.gcode", "G1 X1\n"));
  const json d = f.result("server.files.get_directory", {{"path", "gcodes"}});
  ASSERT_EQ(d["dirs"].size(), 1u);
  EXPECT_EQ(d["dirs"][0]["dirname"], "sub");
  const json l = f.result("server.files.list", {{"root", "gcodes"}});
  ASSERT_EQ(l.size(), 1u);
  EXPECT_EQ(l[0]["path"], "sub/x.gcode");
  EXPECT_FALSE(f.files->write("gcodes", "../x", "no"));
  EXPECT_FALSE(f.files->write("gcodes", "/etc/x", "no"));
  EXPECT_FALSE(f.files->resolve("logs", "x"));
  // "gcodes/." named the root: a forced delete removed every file in it.
  for (const char* root_again : {"gcodes/.", "gcodes/./", "gcodes/sub/..", "gcodes//."}) {
    auto r = f.call(json{
        {"jsonrpc", "2.0"},
        {"method", "server.files.delete_directory"},
        {"params", {{"path", root_again}, {"force", true}}},
        {"id", 3}}.dump());
    ASSERT_EQ(r.size(), 1u);
    EXPECT_TRUE(r[0].contains("error")) << root_again << " " << r[0].dump();
  }
  ASSERT_EQ(f.result("server.files.list", {{"root", "gcodes"}}).size(), 1u);
  EXPECT_EQ(f.result("server.files.delete_file", {{"path", "gcodes/sub/x.gcode"}})["action"],
            "delete_file");
  EXPECT_TRUE(f.result("server.files.list", {{"root", "gcodes"}}).empty());
}

// Metadata of what slicers write, and of hostile lines: a 200 kB move or comment overflowed the
// stack of std::regex (the daemon crashed when a front end asked for the file's metadata); an
// out-of-range number threw out of the scan. Long lines are skipped, numbers out of range ignored.
TEST(WebFiles, MetadataOfSlicerLinesAndOfHostileOnes) {
  Fixture f;
  const std::string huge(200000, '9');
  const std::string text =
      "; generated by OrcaSlicer 2.1.0 on 2026-01-01\n"
      "; estimated printing time (normal mode) = 2d 1h 3m 4s\n"
      ";Filament used: 1.5m\n"
      "; layer_height = 0.2\n"
      "G10 Z99\nG1X5 Z98\nG0 Z0.3 F600 ; Z77\nG1 X1 Z2.5 E1\n"
      "G1 X" +
      huge +
      " Z50\n"
      "; generated by " +
      huge + " " + huge +
      "\n"
      "; estimated printing time (normal mode) = " +
      huge +
      "s\n"
      ";TIME:1e400\n"
      "G1 Z1" +
      std::string(400, '0') + "\n";
  ASSERT_TRUE(f.files->write("gcodes", "hostile.gcode", text));
  const json m = f.result("server.files.metadata", {{"filename", "hostile.gcode"}});
  EXPECT_EQ(m["slicer"], "OrcaSlicer") << m.dump();
  EXPECT_EQ(m["slicer_version"], "2.1.0");
  EXPECT_EQ(m["estimated_time"], 2 * 86400.0 + 3600.0 + 180.0 + 4.0);
  EXPECT_DOUBLE_EQ(m["filament_total"].get<double>(), 1500.0);
  EXPECT_DOUBLE_EQ(m["layer_height"].get<double>(), 0.2);
  EXPECT_DOUBLE_EQ(m["first_layer_height"].get<double>(), 0.3);  // not G10's or the comment's Z
  EXPECT_DOUBLE_EQ(m["object_height"].get<double>(), 2.5);
}

// JSON nested 100 000 deep (200 kB, inside the message limits) parsed, then overflowed the stack
// when stored or echoed (nlohmann dumps by recursion); a database key of 100 000 parts built the
// same nesting. Both are refused with an error, and the connection goes on.
TEST(WebApi, DeeplyNestedJsonAndKeysAreRefused) {
  Fixture f;
  const size_t depth = 100000;
  const std::string deep = std::string(depth, '[') + std::string(depth, ']');
  auto r = f.call(
      R"({"jsonrpc":"2.0","method":"server.database.post_item","params":{"namespace":"n","key":"k","value":)" +
      deep + R"(},"id":7})");
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0]["error"]["code"], -32700);
  EXPECT_NE(r[0]["error"]["message"].get<std::string>().find("deeper than 64"), std::string::npos)
      << r[0].dump();
  std::string key = "a";
  for (size_t i = 1; i < depth; ++i) key += ".a";
  r = f.call(json{
      {"jsonrpc", "2.0"},
      {"method", "server.database.post_item"},
      {"params", {{"namespace", "n"}, {"key", key}, {"value", 1}}},
      {"id", 8}}.dump());
  ASSERT_EQ(r.size(), 1u);
  EXPECT_NE(r[0]["error"]["message"].get<std::string>().find("more than 64 parts"),
            std::string::npos)
      << r[0]["error"].dump();
  // Within the limit: stored and read back (a string holding brackets is no nesting).
  const std::string nested_ok = std::string(60, '[') + "\"]]]]{{{{\"" + std::string(60, ']');
  f.result("server.database.post_item",
           {{"namespace", "n"}, {"key", "k"}, {"value", json::parse(nested_ok)}});
  EXPECT_EQ(f.result("server.database.get_item", {{"namespace", "n"}, {"key", "k"}})["value"],
            json::parse(nested_ok));
}

}  // namespace
}  // namespace feedloop::web
