// OctoPrint's REST API, the part that slicers and their plugins use to send a print: PrusaSlicer,
// SuperSlicer and OrcaSlicer's "OctoPrint" physical printer, Cura's OctoPrint plugin. Moonraker
// offers the same subset (its octoprint_compat component), so a slicer set up for a Klipper
// printer works unchanged: GET /api/version is the connection test, POST /api/files/local the
// upload (multipart: "file", "path", "print"), then /api/job and /api/printer for the state and
// /api/printer/command for G-code. Answers are OctoPrint's shapes, not wrapped in "result".
#include <spdlog/spdlog.h>

#include "core/utf8.hpp"
#include "web/moonraker_api.hpp"

namespace feedloop::web {

using nlohmann::json;

namespace {

constexpr const char* kOctoPrintVersion = "1.5.0";  // the version Moonraker reports

// OctoPrint's state text: "Operational", "Printing", "Paused", "Error".
std::string octoprint_state(const engine::MachineStatus& m, const JobStatus& job) {
  if (m.state == engine::MachineState::kEmergencyStopped || m.state == engine::MachineState::kError)
    return "Error";
  if (job.state == JobState::printing) return "Printing";
  if (job.state == JobState::paused) return "Paused";
  return "Operational";
}

HttpReply reply(int status, const json& body) {
  HttpReply r;
  r.status = status;
  r.body = body.dump(-1, ' ', false, json::error_handler_t::replace);
  return r;
}

// 204 No Content: OctoPrint's answer to a command; no body at all (Beast refuses one).
HttpReply no_content() {
  HttpReply r;
  r.status = 204;
  return r;
}

HttpReply error(int status, const std::string& message) {
  return reply(status, json{{"error", valid_utf8(message)}});
}

// The G-code lines of POST /api/printer/command: {"command": "G28"} or {"commands": [...]}.
Result<std::string> command_script(const std::string& body) {
  const json j = json::parse(body, nullptr, false);
  if (j.is_discarded() || !j.is_object())
    return Error{"expected a JSON object with \"command\" or \"commands\""};
  std::string script;
  if (j.contains("command")) {
    if (!j["command"].is_string()) return Error{"\"command\" must be a string"};
    script = j["command"].get<std::string>();
  } else if (j.contains("commands")) {
    if (!j["commands"].is_array()) return Error{"\"commands\" must be an array of strings"};
    for (const json& c : j["commands"]) {
      if (!c.is_string()) return Error{"\"commands\" must be an array of strings"};
      if (!script.empty()) script += '\n';
      script += c.get<std::string>();
    }
  } else {
    return Error{"expected \"command\" or \"commands\""};
  }
  return script;
}

}  // namespace

void MoonrakerApi::octoprint(const HttpRequest& req, std::function<void(HttpReply)> done) {
  const std::string& p = req.path;
  const bool get = req.method == "GET" || req.method == "HEAD";
  const bool post = req.method == "POST";
  if (p == "/api/version" && get)
    return done(reply(200, json{{"server", kOctoPrintVersion},
                                {"api", "0.1"},
                                {"text", "OctoPrint (feedloop " + options_.version + ")"}}));
  if (p == "/api/server" && get)
    return done(reply(200, json{{"server", kOctoPrintVersion}, {"safemode", nullptr}}));
  if ((p == "/api/login" && post) || (p == "/api/currentuser" && get))
    return done(reply(200, json{{"_is_external_client", false},
                                {"_login_mechanism", "apikey"},
                                {"name", "_api"},
                                {"active", true},
                                {"user", true},
                                {"admin", true},
                                {"apikey", nullptr},
                                {"permissions", json::array()},
                                {"groups", {"admins", "users"}}}));
  if (p == "/api/settings" && get)
    return done(reply(200, json{{"plugins", json::object()},
                                {"feature", {{"sdSupport", false}, {"temperatureGraph", false}}},
                                {"webcam", {{"webcamEnabled", false}}}}));
  if (p == "/api/printerprofiles" && get) {
    const PrinterInfo info = printer_.printer_info();
    return done(reply(200, json{{"profiles",
                                 {{"_default",
                                   {{"id", "_default"},
                                    {"name", info.name},
                                    {"model", info.kinematics},
                                    {"default", true},
                                    {"current", true},
                                    {"heatedBed", true},
                                    {"heatedChamber", false}}}}}}));
  }
  if (p == "/api/files/local" && post) {
    auto stored = store_upload(req, "gcodes");
    if (!stored) return done(error(400, stored.error().message));
    const std::string name = stored->rel.substr(stored->rel.find_last_of('/') + 1);
    return done(reply(201, json{{"done", true},
                                {"files",
                                 {{"local",
                                   {{"name", name},
                                    {"path", stored->rel},
                                    {"origin", "local"},
                                    {"refs",
                                     {{"resource", "/api/files/local/" + stored->rel},
                                      {"download", "/server/files/gcodes/" + stored->rel}}}}}}},
                                {"effectivePrint", stored->print_started}}));
  }
  if (p == "/api/job" && get) {
    const JobStatus job = printer_.job_status();
    const bool has_file = !job.filename.empty();
    json progress = {{"completion", nullptr},
                     {"filepos", nullptr},
                     {"printTime", nullptr},
                     {"printTimeLeft", nullptr},
                     {"printTimeOrigin", nullptr}};
    if (has_file) {
      progress["filepos"] = job.file_position;
      progress["printTime"] = job.print_duration_s;
      if (job.file_size > 0)
        progress["completion"] =
            100.0 * static_cast<double>(job.file_position) / static_cast<double>(job.file_size);
    }
    return done(reply(
        200, json{{"job",
                   {{"file",
                     {{"name", has_file ? json(job.filename) : json(nullptr)},
                      {"path", has_file ? json(job.filename) : json(nullptr)},
                      {"origin", "local"},
                      {"size", has_file ? json(job.file_size) : json(nullptr)}}},
                    {"estimatedPrintTime", nullptr},
                    {"filament", {{"length", nullptr}}},
                    {"user", nullptr}}},
                  {"progress", progress},
                  {"state", octoprint_state(printer_.machine_status(), job)}}));
  }
  if (p == "/api/job" && post) {
    const json j = json::parse(req.body, nullptr, false);
    const std::string command =
        j.is_object() && j.contains("command") && j["command"].is_string() ? j["command"] : "";
    const std::string action =
        j.is_object() && j.contains("action") && j["action"].is_string() ? j["action"] : "toggle";
    std::string why;
    if (command == "cancel") {
      why = printer_.cancel_job();
    } else if (command == "pause") {
      const bool paused = printer_.job_status().state == JobState::paused;
      why = action == "resume" || (action == "toggle" && paused) ? printer_.resume_job()
                                                                  : printer_.pause_job();
    } else if (command == "start" || command == "restart") {
      why = "feedloop has no selected file: upload with print=true, or start it from the UI";
    } else {
      return done(error(400, "unknown job command '" + command + "' (cancel, pause)"));
    }
    if (!why.empty()) return done(error(409, why));
    return done(no_content());
  }
  if (p == "/api/printer" && get) {
    const engine::MachineStatus m = printer_.machine_status();
    const std::string state = octoprint_state(m, printer_.job_status());
    return done(reply(
        200, json{{"temperature",
                   {{"tool0", {{"actual", m.hotend_c}, {"target", m.hotend_target_c}, {"offset", 0}}},
                    {"bed", {{"actual", m.bed_c}, {"target", m.bed_target_c}, {"offset", 0}}}}},
                  {"state",
                   {{"text", state},
                    {"flags",
                     {{"operational", state != "Error"},
                      {"paused", state == "Paused"},
                      {"printing", state == "Printing"},
                      {"cancelling", false},
                      {"pausing", false},
                      {"error", state == "Error"},
                      {"ready", state == "Operational"},
                      {"closedOrError", state == "Error"}}}}}}));
  }
  if (p == "/api/printer/command" && post) {
    auto script = command_script(req.body);
    if (!script) return done(error(400, script.error().message));
    spdlog::info("web: OctoPrint command: {}", valid_utf8(*script));
    return printer_.run_gcode(*script, [done](bool ok, const std::string& response) {
      done(ok ? no_content() : error(409, response));
    });
  }
  done(error(404, "not found: feedloop answers the part of OctoPrint's API that slicers use"));
}

}  // namespace feedloop::web
