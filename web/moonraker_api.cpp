#include "web/moonraker_api.hpp"

#include "web/calibration_report.hpp"

#include <spdlog/spdlog.h>
#include <sys/sysinfo.h>
#include <sys/utsname.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <random>

#include "core/json_depth.hpp"
#include "core/utf8.hpp"
#include "web/multipart.hpp"
#include "web/printer_objects.hpp"

namespace feedloop::web {

using nlohmann::json;

namespace {
constexpr int kMethodNotFound = -32601;

std::string wire(const json& j) {
  return j.dump(-1, ' ', false, json::error_handler_t::replace);
}

HttpReply json_reply(int status, const json& body) {
  HttpReply r;
  r.status = status;
  r.body = wire(body);
  return r;
}

// Moonraker's HTTP error: {"error": {"code", "message"}} with that status.
HttpReply error_reply(int status, const std::string& message) {
  return json_reply(status, json{{"error", {{"code", status}, {"message", valid_utf8(message)}}}});
}

double wall_s() {
  timespec t{};
  clock_gettime(CLOCK_REALTIME, &t);
  return static_cast<double>(t.tv_sec) + static_cast<double>(t.tv_nsec) * 1e-9;
}

// A parameter of the right type, or an error naming it.
struct Params {
  const json& p;
  std::string error;
  std::string str(const char* key, bool required = true, std::string fallback = {}) {
    if (p.is_object() && p.contains(key)) {
      if (p[key].is_string()) return p[key].get<std::string>();
      if (p[key].is_number()) return p[key].dump();
      error = std::string("parameter '") + key + "' must be a string";
    } else if (required && error.empty()) {
      error = std::string("No data for argument: ") + key;
    }
    return fallback;
  }
  int64_t integer(const char* key, int64_t fallback) {
    if (!p.is_object() || !p.contains(key)) return fallback;
    const json& v = p[key];
    if (v.is_number_integer() || v.is_number_unsigned()) return v.get<int64_t>();
    if (v.is_number_float() && std::isfinite(v.get<double>()) && std::fabs(v.get<double>()) < 9e15)
      return static_cast<int64_t>(v.get<double>());
    if (v.is_string()) {
      try {
        return std::stoll(v.get<std::string>());
      } catch (const std::exception&) {
      }
    }
    error = std::string("parameter '") + key + "' must be an integer";
    return fallback;
  }
  bool boolean(const char* key, bool fallback) {
    if (!p.is_object() || !p.contains(key)) return fallback;
    const json& v = p[key];
    if (v.is_boolean()) return v.get<bool>();
    if (v.is_string()) return v.get<std::string>() == "true";
    error = std::string("parameter '") + key + "' must be true or false";
    return fallback;
  }
};

int code_for(const std::string& message) {
  return message.size() >= 9 && message.compare(message.size() - 9, 9, "not found") == 0 ? 404
                                                                                         : 400;
}

// /proc readers for machine.proc_stats and machine.system_info.
double process_cpu_s() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + static_cast<double>(t.tv_nsec) * 1e-9;
}
int64_t rss_kb() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::atoll(line.c_str() + 6);
  return 0;
}
std::string os_release(const std::string& key) {
  std::ifstream in("/etc/os-release");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind(key + "=", 0) == 0) {
      std::string v = line.substr(key.size() + 1);
      if (v.size() >= 2 && v.front() == '"') v = v.substr(1, v.size() - 2);
      return v;
    }
  return {};
}

// The G-code commands the web API runs itself (Klipper's pause_resume, virtual_sdcard and
// RESTART), by their first word.
std::string first_word_upper(const std::string& line) {
  size_t b = line.find_first_not_of(" \t");
  if (b == std::string::npos) return {};
  size_t e = line.find_first_of(" \t;", b);
  std::string w = line.substr(b, e == std::string::npos ? std::string::npos : e - b);
  for (char& c : w) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return w;
}
}  // namespace

struct MoonrakerApi::Connection {
  Send send;
  json subscription = json::object();  // object -> null (all fields) or [fields]
  json last = json::object();          // what was last sent, per object
  std::string client_name;
};

MoonrakerApi::MoonrakerApi(PrinterBackend& printer, FileStore& files, Database& db, Options options)
    : printer_(printer), files_(files), db_(db), options_(std::move(options)) {
  register_methods();
}

MoonrakerApi::~MoonrakerApi() = default;

uint64_t MoonrakerApi::open_connection(Send send) {
  const uint64_t id = next_conn_++;
  auto c = std::make_unique<Connection>();
  c->send = std::move(send);
  conns_[id] = std::move(c);
  return id;
}

void MoonrakerApi::close_connection(uint64_t id) {
  conns_.erase(id);
}

double MoonrakerApi::eventtime() const {
  return now_s_;
}

void MoonrakerApi::send(uint64_t conn, std::shared_ptr<const std::string> text) {
  auto it = conns_.find(conn);
  if (it == conns_.end()) return;
  if (!it->second->send(std::move(text))) conns_.erase(conn);  // dropped: a slow reader
}

void MoonrakerApi::broadcast(const std::string& method, json params) {
  auto text = std::make_shared<const std::string>(
      wire(json{{"jsonrpc", "2.0"}, {"method", method}, {"params", std::move(params)}}));
  std::vector<uint64_t> ids;
  for (auto& [id, c] : conns_) ids.push_back(id);
  for (uint64_t id : ids) {
    send(id, text);
    ++notifications_sent_;
  }
}

void MoonrakerApi::gcode_response(const std::string& text) {
  gcode_store_.push_back({text, wall_s(), "response"});
  while (gcode_store_.size() > options_.gcode_store_size) gcode_store_.pop_front();
  broadcast("notify_gcode_response", json::array({text}));
}

void MoonrakerApi::on_message(uint64_t conn, std::string_view text) {
  ++requests_;
  // A job's end seen by a client is in the history before anything the client does next (a
  // start right after "complete" is a new job, not the same one going on).
  track_jobs(now_s_);
  auto error_reply = [&](int code, const std::string& message) {
    send(conn, std::make_shared<const std::string>(
                   wire(json{{"jsonrpc", "2.0"},
                             {"error", {{"code", code}, {"message", message}}},
                             {"id", nullptr}})));
  };
  if (json_nesting_depth(text) > kMaxClientJsonDepth) {
    error_reply(-32700, "Parse error: nested deeper than " + std::to_string(kMaxClientJsonDepth) +
                            " levels");
    return;
  }
  json msg = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (msg.is_discarded()) {
    error_reply(-32700, "Parse error");
    return;
  }
  if (msg.is_array()) {
    // A batch: one array reply once every request has answered (JSON-RPC 2.0 Sect. 6).
    if (msg.empty() || msg.size() > 256) {
      error_reply(-32600, msg.empty() ? "Invalid Request: an empty batch"
                                      : "Invalid Request: more than 256 requests in a batch");
      return;
    }
    struct Batch {
      json replies = json::array();
      size_t waiting = 0;
    };
    auto batch = std::make_shared<Batch>();
    batch->waiting = msg.size();
    for (const json& r : msg) {
      handle(conn, r, [this, conn, batch](json reply) {
        if (!reply.is_null()) batch->replies.push_back(std::move(reply));
        if (--batch->waiting == 0 && !batch->replies.empty())
          send(conn, std::make_shared<const std::string>(wire(batch->replies)));
      });
    }
    return;
  }
  handle(conn, msg, [this, conn](json reply) {
    if (!reply.is_null()) send(conn, std::make_shared<const std::string>(wire(reply)));
  });
}

// One request; `reply` gets the response (null for a notification), exactly once.
void MoonrakerApi::handle(uint64_t conn, const json& req, std::function<void(json)> reply) {
  if (!req.is_object() || !req.contains("method") || !req["method"].is_string()) {
    reply(json{{"jsonrpc", "2.0"},
               {"error", {{"code", -32600}, {"message", "Invalid Request"}}},
               {"id", nullptr}});
    return;
  }
  const bool notification = !req.contains("id");
  json id = notification ? json(nullptr) : req["id"];
  if (!id.is_null() && !id.is_string() && !id.is_number()) id = nullptr;
  const std::string method = req["method"].get<std::string>();
  const json params = req.contains("params") ? req["params"] : json::object();
  try {
    call(conn, method, params, [reply, id, notification](json result, int code, std::string error) {
      if (notification) {
        reply(nullptr);
        return;
      }
      if (!error.empty() || code != 0)
        reply(json{{"jsonrpc", "2.0"},
                   {"error", {{"code", code}, {"message", valid_utf8(error)}}},
                   {"id", id}});
      else
        reply(json{{"jsonrpc", "2.0"}, {"result", std::move(result)}, {"id", id}});
    });
  } catch (const std::exception& e) {
    reply(
        json{{"jsonrpc", "2.0"},
             {"error",
              {{"code", 500}, {"message", std::string("internal error: ") + valid_utf8(e.what())}}},
             {"id", id}});
  }
}

void MoonrakerApi::call(uint64_t conn, const std::string& method, const json& params, Done done) {
  auto it = methods_.find(method);
  // Each call and its outcome at debug level (`feedloopd --log-level debug`): what a UI sends.
  if (spdlog::should_log(spdlog::level::debug)) {
    spdlog::debug("web: call {} {}", method,
                  params.dump(-1, ' ', false, json::error_handler_t::replace).substr(0, 200));
    done = [method, inner = std::move(done)](json result, int code, std::string error) {
      if (!error.empty() || code != 0) spdlog::debug("web: {} failed: {} {}", method, code, error);
      inner(std::move(result), code, std::move(error));
    };
  }
  if (it == methods_.end()) {
    done(nullptr, kMethodNotFound, "Method not found");
    return;
  }
  if (!params.is_object() && !params.is_null()) {
    done(nullptr, -32602, "Invalid params: expected an object");
    return;
  }
  it->second(conn, params.is_null() ? json::object() : params, std::move(done));
}

json MoonrakerApi::all_objects() const {
  const PrinterInfo info = printer_.printer_info();
  const engine::MachineStatus s = printer_.machine_status();
  const engine::ServoStatus v = printer_.servo_status();
  const JobStatus job = printer_.job_status();
  const std::string gcodes = files_.root_dir("gcodes");
  const planner::ObjectLabels objects = printer_.object_labels();
  return printer_objects(ObjectInputs{info, s, v, job, telemetry_, gcodes, objects});
}

json MoonrakerApi::filtered(const json& all, const json& wanted) const {
  json out = json::object();
  if (!wanted.is_object()) return out;
  for (auto& [name, fields] : wanted.items()) {
    if (!all.contains(name)) continue;
    const json& obj = all[name];
    if (fields.is_null() || (fields.is_array() && fields.empty())) {
      out[name] = obj;
      continue;
    }
    json part = json::object();
    if (fields.is_array())
      for (const json& f : fields)
        if (f.is_string() && obj.contains(f.get<std::string>()))
          part[f.get<std::string>()] = obj[f.get<std::string>()];
    out[name] = part;
  }
  return out;
}

void MoonrakerApi::run_script(std::vector<std::string> lines, size_t next, Done done) {
  // Lines the web API runs itself are taken one at a time; the others go to the printer in runs.
  while (next < lines.size()) {
    const std::string word = first_word_upper(lines[next]);
    std::string err;
    bool handled = true;
    if (word == "PAUSE" || word == "M25")
      err = printer_.pause_job();
    else if (word == "RESUME" || word == "M24")
      err = printer_.resume_job();
    else if (word == "CANCEL_PRINT")
      err = printer_.cancel_job();
    else if (word == "SDCARD_RESET_FILE")
      err = printer_.reset_job();
    else if (word == "RESTART" || word == "FIRMWARE_RESTART")
      printer_.restart();
    else if (word == "SDCARD_PRINT_FILE") {
      const std::string& l = lines[next];
      std::string upper = l;
      for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
      const size_t at = upper.find("FILENAME=");
      std::string name = at == std::string::npos ? std::string() : l.substr(at + 9);
      while (!name.empty() && (name.back() == ' ' || name.back() == '\r')) name.pop_back();
      if (name.size() >= 2 && name.front() == '"') name = name.substr(1, name.size() - 2);
      auto path = files_.resolve("gcodes", name);
      err = name.empty() ? "SDCARD_PRINT_FILE needs FILENAME="
            : !path      ? path.error().message
                         : printer_.start_job(*path, name);
    } else {
      handled = false;
    }
    if (handled) {
      if (!err.empty()) {
        gcode_response("!! " + err);
        done(nullptr, 400, err);
        return;
      }
      ++next;
      continue;
    }
    // A run of ordinary lines.
    size_t end = next;
    std::string script;
    while (end < lines.size()) {
      const std::string w = first_word_upper(lines[end]);
      if (w == "PAUSE" || w == "M25" || w == "RESUME" || w == "M24" || w == "CANCEL_PRINT" ||
          w == "SDCARD_RESET_FILE" || w == "RESTART" || w == "FIRMWARE_RESTART" ||
          w == "SDCARD_PRINT_FILE")
        break;
      script += lines[end++];
      script += '\n';
    }
    script.pop_back();
    printer_.run_gcode(std::move(script), [this, lines = std::move(lines), end, done](
                                              bool ok, std::string response) mutable {
      // The printer's answer lines, without Marlin's "ok" (Klipper sends no "ok" to the console).
      size_t b = 0;
      while (b < response.size()) {
        size_t e = response.find('\n', b);
        if (e == std::string::npos) e = response.size();
        std::string l = response.substr(b, e - b);
        if (l.rfind("ok ", 0) == 0) l = l.substr(3);
        if (!l.empty() && l != "ok") gcode_response(ok ? l : "!! " + l);
        b = e + 1;
      }
      if (!ok) {
        done(nullptr, 400, response);
        return;
      }
      run_script(std::move(lines), end, std::move(done));
    });
    return;
  }
  done("ok", 0, {});
}

bool MoonrakerApi::is_api_path(std::string_view path) {
  for (std::string_view p :
       {"/server/", "/printer/", "/machine/", "/access/", "/api/", "/websocket"})
    if (path.substr(0, p.size()) == p) return true;
  return false;
}

void MoonrakerApi::on_http(const HttpRequest& req, std::function<void(HttpReply)> done) {
  ++requests_;
  track_jobs(now_s_);  // as in on_message
  auto reply_json = [done](int status, const json& body) { done(json_reply(status, body)); };
  auto error = [done](int status, const std::string& message) {
    done(error_reply(status, message));
  };
  if (req.path.rfind("/api/", 0) == 0) return octoprint(req, done);
  // Files: GET /server/files/<root>/<path> downloads, DELETE deletes, POST upload uploads.
  if (req.path == "/server/files/upload" && req.method == "POST") {
    upload(req, done);
    return;
  }
  static const std::string kFiles = "/server/files/";
  if (req.path.rfind(kFiles, 0) == 0 && req.path.find('/', kFiles.size()) != std::string::npos) {
    const std::string rest = req.path.substr(kFiles.size());
    auto rr = FileStore::split_root(rest);
    if (rr) {
      auto p = files_.resolve(rr->first, rr->second);
      if (!p) return error(400, p.error().message);
      if (req.method == "DELETE") {
        auto r = files_.remove(rest);
        if (!r) return error(code_for(r.error().message), r.error().message);
        broadcast("notify_filelist_changed", json::array({*r}));
        return reply_json(200, json{{"result", *r}});
      }
      HttpReply r;
      r.file_path = *p;
      r.content_type = "application/octet-stream";
      done(std::move(r));
      return;
    }
  }
  // The rest maps onto the JSON-RPC methods: /a/b/c -> a.b.c, with Moonraker's exceptions.
  std::string method = req.path.substr(1);
  std::replace(method.begin(), method.end(), '/', '.');
  if (method == "server.database.item")
    method = req.method == "POST"     ? "server.database.post_item"
             : req.method == "DELETE" ? "server.database.delete_item"
                                      : "server.database.get_item";
  else if (method == "server.files.directory")
    method = req.method == "POST"     ? "server.files.post_directory"
             : req.method == "DELETE" ? "server.files.delete_directory"
                                      : "server.files.get_directory";
  else if (method == "server.history.job")
    method = req.method == "DELETE" ? "server.history.delete_job" : "server.history.get_job";
  else if (method == "printer.objects.query" || method == "printer.objects.list" ||
           method == "printer.info") {
  }
  json params = json::object();
  for (auto& [k, v] : req.query) params[k] = v;
  if (method == "printer.objects.query") {
    // ?toolhead&extruder=target,temperature
    json objects = json::object();
    for (auto& [k, v] : req.query) {
      if (v.empty()) {
        objects[k] = nullptr;
        continue;
      }
      json fields = json::array();
      size_t b = 0;
      while (b <= v.size()) {
        size_t e = v.find(',', b);
        if (e == std::string::npos) e = v.size();
        fields.push_back(v.substr(b, e - b));
        b = e + 1;
      }
      objects[k] = fields;
    }
    params = json{{"objects", objects}};
  }
  if (!req.body.empty() && req.content_type.find("json") != std::string::npos) {
    if (json_nesting_depth(req.body) > kMaxClientJsonDepth)
      return error(400, "the request body nests deeper than " +
                            std::to_string(kMaxClientJsonDepth) + " levels");
    json body = json::parse(req.body, nullptr, false);
    if (body.is_discarded() || !body.is_object())
      return error(400, "the request body is not a JSON object");
    for (auto& [k, v] : body.items()) params[k] = v;
  }
  call(0, method, params, [reply_json, error](json result, int code, std::string message) {
    if (code == kMethodNotFound) return error(404, "Not Found");
    if (code != 0) return error(code >= 400 && code < 600 ? code : 400, message);
    reply_json(200, json{{"result", std::move(result)}});
  });
}

void MoonrakerApi::upload(const HttpRequest& req, std::function<void(HttpReply)> done) {
  auto stored = store_upload(req);
  if (!stored) return done(error_reply(400, stored.error().message));
  done(json_reply(201, json{{"result",
                             {{"item", stored->item},
                              {"print_started", stored->print_started},
                              {"print_queued", false},
                              {"action", "create_file"}}}}));
}

Result<MoonrakerApi::StoredUpload> MoonrakerApi::store_upload(const HttpRequest& req,
                                                              const std::string& forced_root) {
  auto form = parse_multipart(req.content_type, req.bytes());
  if (!form) return form.error();
  if (!form->has_file) return Error{"No file part in the upload (field 'file')"};
  auto field = [&](const char* k, std::string fallback) {
    auto it = form->fields.find(k);
    return it == form->fields.end() ? fallback : it->second;
  };
  const std::string root = forced_root.empty() ? field("root", "gcodes") : forced_root;
  std::string dir = field("path", "");
  while (!dir.empty() && dir.back() == '/') dir.pop_back();
  std::string name = form->file_name;
  if (const size_t slash = name.find_last_of("/\\"); slash != std::string::npos)
    name = name.substr(slash + 1);
  if (name.empty()) return Error{"the uploaded file has no name"};
  const std::string rel = dir.empty() ? name : dir + "/" + name;
  if (root == "gcodes") {
    if (const std::string why = printer_.job_name_error(rel); !why.empty())
      return Error{"cannot print '" + rel + "': " + why};
  }
  auto item = files_.write(root, rel, form->file);
  if (!item) return item.error();
  spdlog::info("web: uploaded {}/{} ({} bytes)", root, rel, form->file.size());
  StoredUpload out{*item, rel, false};
  if (field("print", "false") == "true" && root == "gcodes") {
    auto path = files_.resolve(root, rel);
    if (path && printer_.start_job(*path, rel).empty()) out.print_started = true;
  }
  broadcast("notify_filelist_changed", json::array({{{"action", "create_file"}, {"item", *item}}}));
  return out;
}

json MoonrakerApi::proc_stats(double now_s) {
  const double cpu = process_cpu_s();
  if (now_s > last_cpu_wall_s_ + 0.5) {
    if (last_cpu_wall_s_ > 0) cpu_usage_ = 100.0 * (cpu - last_cpu_s_) / (now_s - last_cpu_wall_s_);
    last_cpu_s_ = cpu;
    last_cpu_wall_s_ = now_s;
  }
  struct sysinfo si {};
  sysinfo(&si);
  const double unit_kb = static_cast<double>(si.mem_unit) / 1024.0;
  const double total = static_cast<double>(si.totalram) * unit_kb,
               avail = static_cast<double>(si.freeram + si.bufferram) * unit_kb;
  return {
      {"moonraker_stats",
       {{"time", wall_s()}, {"cpu_usage", cpu_usage_}, {"memory", rss_kb()}, {"mem_units", "kB"}}},
      {"cpu_temp", nullptr},
      {"network", json::object()},
      {"system_cpu_usage", {{"cpu", cpu_usage_}}},
      {"system_memory", {{"total", total}, {"available", avail}, {"used", total - avail}}},
      {"system_uptime", static_cast<double>(si.uptime)},
      {"websocket_connections", conns_.size()}};
}

void MoonrakerApi::track_jobs(double now_s) {
  (void)now_s;
  const JobStatus job = printer_.job_status();
  // A print streamed by a client (no file) is not a history job: Moonraker records the prints
  // of virtual_sdcard only.
  const bool was_active =
      (last_job_state_ == JobState::printing || last_job_state_ == JobState::paused) &&
      !last_job_file_.empty();
  const bool active =
      (job.state == JobState::printing || job.state == JobState::paused) && !job.filename.empty();
  if (active && (!was_active || job.filename != last_job_file_)) {
    job_ = json{{"user", "_TRUSTED_USER_"},
                {"filename", job.filename},
                {"status", "in_progress"},
                {"start_time", wall_s()},
                {"end_time", nullptr},
                {"print_duration", 0.0},
                {"total_duration", 0.0},
                {"filament_used", 0.0},
                {"metadata", json::object()},
                {"auxiliary_data", json::array()},
                {"exists", true}};
    if (auto m = files_.metadata(job.filename)) job_["metadata"] = *m;
    job_row_ = db_.add_job(job_);
    json j = job_;
    j["job_id"] = std::to_string(job_row_);
    broadcast("notify_history_changed", json::array({{{"action", "added"}, {"job", j}}}));
  }
  if (job_row_ >= 0 && was_active && !active) {
    job_["status"] = job.state == JobState::complete    ? "completed"
                     : job.state == JobState::cancelled ? "cancelled"
                     : job.state == JobState::error     ? "error"
                                                        : "interrupted";
    job_["end_time"] = wall_s();
    job_["print_duration"] = job.print_duration_s;
    job_["total_duration"] = job.total_duration_s;
    job_["filament_used"] = job.filament_used_mm;
    db_.update_job(job_row_, job_);
    json j = job_;
    j["job_id"] = std::to_string(job_row_);
    broadcast("notify_history_changed", json::array({{{"action", "finished"}, {"job", j}}}));
    job_row_ = -1;
  }
  last_job_state_ = job.state;
  last_job_file_ = job.filename;
}

void MoonrakerApi::tick(double now_s) {
  now_s_ = now_s;
  if (start_s_ < 0) start_s_ = now_s;
  const engine::MachineStatus s = printer_.machine_status();
  telemetry_.sample(now_s - start_s_, s);
  track_jobs(now_s);
  // Klippy state changes.
  const std::string state = webhooks_state(s);
  if (state != last_webhooks_state_) {
    if (state == "shutdown")
      broadcast("notify_klippy_shutdown", json::array());
    else
      broadcast("notify_klippy_ready", json::array());
    last_webhooks_state_ = state;
  }
  if (now_s - last_temp_s_ >= 1.0) {
    last_temp_s_ = now_s;
    auto add = [this](const char* name, double t, double target, double power) {
      TempSeries& ts = temps_[name];
      ts.temps.push_back(std::round(t * 100) / 100);
      ts.targets.push_back(target);
      ts.powers.push_back(std::round(power * 1000) / 1000);
      while (ts.temps.size() > options_.temperature_store_size) {
        ts.temps.pop_front();
        ts.targets.pop_front();
        ts.powers.pop_front();
      }
    };
    const HeaterPowers p = heater_powers(s);
    add("extruder", s.hotend_c, s.hotend_target_c, p.hotend);
    add("heater_bed", s.bed_c, s.bed_target_c, p.bed);
  }
  if (now_s - last_proc_s_ >= 1.0) {
    last_proc_s_ = now_s;
    broadcast("notify_proc_stat_update", json::array({proc_stats(now_s)}));
  }
  if (now_s - last_status_s_ >= options_.status_period_s) {
    last_status_s_ = now_s;
    bool any = false;
    for (auto& [id, c] : conns_)
      if (!c->subscription.empty()) any = true;
    if (!any) return;
    const json all = all_objects();
    std::vector<uint64_t> ids;
    for (auto& [id, c] : conns_) ids.push_back(id);
    for (uint64_t id : ids) {
      auto it = conns_.find(id);
      if (it == conns_.end() || it->second->subscription.empty()) continue;
      Connection& c = *it->second;
      const json now = filtered(all, c.subscription);
      json diff = json::object();
      for (auto& [name, obj] : now.items()) {
        const json* before = c.last.contains(name) ? &c.last[name] : nullptr;
        for (auto& [field, value] : obj.items())
          if (!before || !before->contains(field) || (*before)[field] != value)
            diff[name][field] = value;
      }
      if (diff.empty()) continue;
      c.last = now;
      ++notifications_sent_;
      send(id,
           std::make_shared<const std::string>(wire(json{{"jsonrpc", "2.0"},
                                                         {"method", "notify_status_update"},
                                                         {"params", json::array({diff, now_s})}})));
    }
  }
}

void MoonrakerApi::register_methods() {
  auto& m = methods_;
  auto ok = [](Done& d, json r) { d(std::move(r), 0, {}); };
  auto fail = [](Done& d, const std::string& e) { d(nullptr, code_for(e), e); };

  m["server.connection.identify"] = [this, ok](uint64_t conn, const json& p, Done d) {
    if (auto it = conns_.find(conn); it != conns_.end())
      it->second->client_name = Params{p}.str("client_name", false);
    ok(d, {{"connection_id", conn}});
  };
  m["server.websocket.id"] = [ok](uint64_t conn, const json&, Done d) {
    ok(d, {{"websocket_id", conn}});
  };
  m["server.info"] = [this, ok](uint64_t, const json&, Done d) {
    const std::string state = webhooks_state(printer_.machine_status());
    ok(d, {{"klippy_connected", true},
           {"klippy_state", state},
           {"components",
            {"klippy_connection", "application", "websockets", "database", "file_manager",
             "klippy_apis", "machine", "data_store", "proc_stats", "job_state", "job_queue",
             "history", "webcam", "announcements"}},
           {"failed_components", json::array()},
           {"registered_directories", FileStore::roots()},
           {"warnings", json::array()},
           {"websocket_count", conns_.size()},
           {"moonraker_version", "v0.9.3-feedloop-" + options_.version},
           {"missing_klippy_requirements", json::array()},
           {"api_version", {1, 5, 0}},
           {"api_version_string", "1.5.0"}});
  };
  m["server.config"] = [this, ok](uint64_t, const json&, Done d) {
    ok(d,
       {{"config",
         {{"server", {{"host", options_.host}, {"port", options_.port}}},
          {"file_manager", {{"enable_object_processing", false}, {"queue_gcode_uploads", false}}}}},
        {"orig", json::object()},
        {"files", json::array()}});
  };
  m["server.restart"] = [ok](uint64_t, const json&, Done d) { ok(d, "ok"); };
  m["printer.info"] = [this, ok](uint64_t, const json&, Done d) {
    const PrinterInfo info = printer_.printer_info();
    const engine::MachineStatus s = printer_.machine_status();
    const std::string state = webhooks_state(s);
    char host[256] = {};
    gethostname(host, sizeof host - 1);
    ok(d, {{"state", state},
           {"state_message", state == "ready"
                                 ? std::string("Printer is ready")
                                 : std::string(s.last_error[0] ? s.last_error : "Emergency stop")},
           {"hostname", host},
           {"software_version", "feedloop " + info.version},
           {"cpu_info", ""},
           {"klipper_path", ""},
           {"python_path", ""},
           {"log_file", ""},
           {"config_file", ""},
           {"app", "feedloop"}});
  };
  m["printer.objects.list"] = [this, ok](uint64_t, const json&, Done d) {
    json names = json::array();
    const json all = all_objects();
    for (auto& [k, v] : all.items()) names.push_back(k);
    ok(d, {{"objects", names}});
  };
  m["printer.objects.query"] = [this, ok, fail](uint64_t, const json& p, Done d) {
    if (!p.contains("objects") || !p["objects"].is_object())
      return fail(d, "parameter 'objects' must be an object");
    ok(d, {{"eventtime", eventtime()}, {"status", filtered(all_objects(), p["objects"])}});
  };
  m["printer.objects.subscribe"] = [this, ok, fail](uint64_t conn, const json& p, Done d) {
    if (p.contains("objects") && !p["objects"].is_object())
      return fail(d, "parameter 'objects' must be an object");
    const json wanted = p.value("objects", json::object());
    const json now = filtered(all_objects(), wanted);
    if (auto it = conns_.find(conn); it != conns_.end()) {
      it->second->subscription = wanted;
      it->second->last = now;
    }
    ok(d, {{"eventtime", eventtime()}, {"status", now}});
  };
  m["printer.query_endstops.status"] = [ok](uint64_t, const json&, Done d) {
    ok(d, {{"x", "open"}, {"y", "open"}, {"z", "open"}});
  };
  m["printer.gcode.help"] = [ok](uint64_t, const json&, Done d) {
    json h = json::object();
    for (auto& [k, v] : gcode_commands().items()) h[k] = v["help"];
    ok(d, h);
  };
  m["printer.gcode.script"] = [this, fail](uint64_t, const json& p, Done d) {
    Params pp{p};
    const std::string script = pp.str("script");
    if (!pp.error.empty()) return fail(d, pp.error);
    if (script.size() > 64 * 1024) return fail(d, "script longer than 64 KiB");
    gcode_store_.push_back({script, wall_s(), "command"});
    while (gcode_store_.size() > options_.gcode_store_size) gcode_store_.pop_front();
    std::vector<std::string> lines;
    size_t b = 0;
    while (b <= script.size()) {
      size_t e = script.find('\n', b);
      if (e == std::string::npos) e = script.size();
      std::string l = script.substr(b, e - b);
      if (l.find_first_not_of(" \t\r") != std::string::npos) lines.push_back(std::move(l));
      b = e + 1;
    }
    run_script(std::move(lines), 0, std::move(d));
  };
  m["printer.emergency_stop"] = [this, ok](uint64_t, const json&, Done d) {
    printer_.emergency_stop("emergency stop from the web UI");
    ok(d, "ok");
  };
  m["printer.restart"] = [this, ok](uint64_t, const json&, Done d) {
    printer_.restart();
    ok(d, "ok");
  };
  m["printer.firmware_restart"] = m["printer.restart"];
  m["printer.print.start"] = [this, ok, fail](uint64_t, const json& p, Done d) {
    Params pp{p};
    const std::string name = pp.str("filename");
    if (!pp.error.empty()) return fail(d, pp.error);
    auto path = files_.resolve("gcodes", name);
    if (!path) return fail(d, path.error().message);
    if (std::string e = printer_.start_job(*path, name); !e.empty()) return fail(d, e);
    ok(d, "ok");
  };
  m["printer.print.pause"] = [this, ok, fail](uint64_t, const json&, Done d) {
    if (std::string e = printer_.pause_job(); !e.empty()) return fail(d, e);
    ok(d, "ok");
  };
  m["printer.print.resume"] = [this, ok, fail](uint64_t, const json&, Done d) {
    if (std::string e = printer_.resume_job(); !e.empty()) return fail(d, e);
    ok(d, "ok");
  };
  m["printer.print.cancel"] = [this, ok, fail](uint64_t, const json&, Done d) {
    if (std::string e = printer_.cancel_job(); !e.empty()) return fail(d, e);
    ok(d, "ok");
  };
  // Files.
  m["server.files.roots"] = [this, ok](uint64_t, const json&, Done d) {
    json r = json::array();
    for (const std::string& root : FileStore::roots())
      r.push_back({{"name", root}, {"path", files_.root_dir(root)}, {"permissions", "rw"}});
    ok(d, r);
  };
  m["server.files.list"] = [this, ok, fail](uint64_t, const json& p, Done d) {
    Params pp{p};
    auto r = files_.list(pp.str("root", false, "gcodes"));
    if (!pp.error.empty()) return fail(d, pp.error);
    if (!r) return fail(d, r.error().message);
    ok(d, *r);
  };
  m["server.files.get_directory"] = [this, ok, fail](uint64_t, const json& p, Done d) {
    Params pp{p};
    auto r = files_.directory(pp.str("path", false, "gcodes"));
    if (!pp.error.empty()) return fail(d, pp.error);
    if (!r) return fail(d, r.error().message);
    ok(d, *r);
  };
  m["server.files.metadata"] = [this, ok, fail](uint64_t, const json& p, Done d) {
    Params pp{p};
    const std::string name = pp.str("filename");
    if (!pp.error.empty()) return fail(d, pp.error);
    auto r = files_.metadata(name);
    if (!r) return fail(d, r.error().message);
    ok(d, *r);
  };
  m["server.files.metascan"] = m["server.files.metadata"];
  m["server.files.thumbnails"] = [ok](uint64_t, const json&, Done d) { ok(d, json::array()); };
  m["server.files.delete_file"] = [this, ok, fail](uint64_t, const json& p, Done d) {
    Params pp{p};
    const std::string path = pp.str("path");
    if (!pp.error.empty()) return fail(d, pp.error);
    auto r = files_.remove(path);
    if (!r) return fail(d, r.error().message);
    broadcast("notify_filelist_changed", json::array({*r}));
    ok(d, *r);
  };
  m["server.files.post_directory"] = [this, ok, fail](uint64_t, const json& p, Done d) {
    Params pp{p};
    const std::string path = pp.str("path");
    if (!pp.error.empty()) return fail(d, pp.error);
    auto r = files_.make_dir(path);
    if (!r) return fail(d, r.error().message);
    broadcast("notify_filelist_changed", json::array({*r}));
    ok(d, *r);
  };
  m["server.files.delete_directory"] = [this, ok, fail](uint64_t, const json& p, Done d) {
    Params pp{p};
    const std::string path = pp.str("path");
    const bool force = pp.boolean("force", false);
    if (!pp.error.empty()) return fail(d, pp.error);
    auto r = files_.remove_dir(path, force);
    if (!r) return fail(d, r.error().message);
    broadcast("notify_filelist_changed", json::array({*r}));
    ok(d, *r);
  };
  // Database.
  m["server.database.list"] = [this, ok](uint64_t, const json&, Done d) {
    ok(d, {{"namespaces", db_.namespaces()}, {"backups", json::array()}});
  };
  m["server.database.get_item"] = [this, ok, fail](uint64_t, const json& p, Done d) {
    Params pp{p};
    const std::string ns = pp.str("namespace");
    const std::string key = pp.str("key", false);
    if (!pp.error.empty()) return fail(d, pp.error);
    auto v = db_.get(ns, key);
    if (!v) return fail(d, v.error().message);
    ok(d, {{"namespace", ns}, {"key", key.empty() ? json(nullptr) : json(key)}, {"value", *v}});
  };
  m["server.database.post_item"] = [this, ok, fail](uint64_t, const json& p, Done d) {
    Params pp{p};
    const std::string ns = pp.str("namespace");
    const std::string key = pp.str("key");
    if (!pp.error.empty()) return fail(d, pp.error);
    if (!p.contains("value")) return fail(d, "No data for argument: value");
    if (Status s = db_.post(ns, key, p["value"]); !s) return fail(d, s.error().message);
    ok(d, {{"namespace", ns}, {"key", key}, {"value", p["value"]}});
  };
  m["server.database.delete_item"] = [this, ok, fail](uint64_t, const json& p, Done d) {
    Params pp{p};
    const std::string ns = pp.str("namespace");
    const std::string key = pp.str("key");
    if (!pp.error.empty()) return fail(d, pp.error);
    auto v = db_.remove(ns, key);
    if (!v) return fail(d, v.error().message);
    ok(d, {{"namespace", ns}, {"key", key}, {"value", *v}});
  };
  // History.
  m["server.history.list"] = [this, ok, fail](uint64_t, const json& p, Done d) {
    Params pp{p};
    const int64_t start = std::max<int64_t>(0, pp.integer("start", 0));
    const int64_t limit = std::clamp<int64_t>(pp.integer("limit", 50), 1, 1000);
    if (!pp.error.empty()) return fail(d, pp.error);
    ok(d, {{"count", db_.job_count()}, {"jobs", db_.jobs(start, limit)}});
  };
  m["server.history.totals"] = [this, ok](uint64_t, const json&, Done d) {
    const json jobs = db_.jobs(0, 1'000'000);
    double total = 0, print = 0, filament = 0, longest_job = 0, longest_print = 0;
    for (const json& j : jobs) {
      const double t = j.value("total_duration", 0.0), pr = j.value("print_duration", 0.0);
      total += t;
      print += pr;
      filament += j.value("filament_used", 0.0);
      longest_job = std::max(longest_job, t);
      longest_print = std::max(longest_print, pr);
    }
    ok(d, {{"job_totals",
            {{"total_jobs", jobs.size()},
             {"total_time", total},
             {"total_print_time", print},
             {"total_filament_used", filament},
             {"longest_job", longest_job},
             {"longest_print", longest_print}}},
           {"auxiliary_totals", json::array()}});
  };
  m["server.history.delete_job"] = [this, ok, fail](uint64_t, const json& p, Done d) {
    Params pp{p};
    const bool all = pp.boolean("all", false);
    const std::string uid = all ? std::string("all") : pp.str("uid");
    if (!pp.error.empty()) return fail(d, pp.error);
    if (Status s = db_.delete_job(uid); !s) return fail(d, s.error().message);
    ok(d, {{"deleted_jobs", json::array({uid})}});
  };
  m["server.history.reset_totals"] = [ok](uint64_t, const json&, Done d) {
    ok(d, {{"last_totals", {{"total_jobs", 0}}}});
  };
  // Stores.
  m["server.temperature_store"] = [this, ok](uint64_t, const json&, Done d) {
    json r = json::object();
    for (auto& [name, ts] : temps_)
      r[name] = {{"temperatures", ts.temps}, {"targets", ts.targets}, {"powers", ts.powers}};
    ok(d, r);
  };
  m["server.gcode_store"] = [this, ok, fail](uint64_t, const json& p, Done d) {
    Params pp{p};
    const auto count = static_cast<size_t>(std::clamp<int64_t>(pp.integer("count", 100), 0, 10000));
    if (!pp.error.empty()) return fail(d, pp.error);
    json r = json::array();
    for (size_t i = gcode_store_.size() > count ? gcode_store_.size() - count : 0;
         i < gcode_store_.size(); ++i)
      r.push_back({{"message", gcode_store_[i].message},
                   {"time", gcode_store_[i].time},
                   {"type", gcode_store_[i].type}});
    ok(d, {{"gcode_store", r}});
  };
  // Machine.
  m["machine.system_info"] = [ok](uint64_t, const json&, Done d) {
    struct utsname u {};
    uname(&u);
    struct sysinfo si {};
    sysinfo(&si);
    const std::string version = os_release("VERSION_ID");
    ok(d, {{"system_info",
            {{"python",
              {{"version", {3, 11, 2, "final", 0}}, {"version_string", "none (feedloop is C++)"}}},
             {"cpu_info",
              {{"cpu_count", sysconf(_SC_NPROCESSORS_ONLN)},
               {"bits", "64bit"},
               {"processor", u.machine},
               {"cpu_desc", ""},
               {"serial_number", ""},
               {"hardware_desc", ""},
               {"model", ""},
               {"total_memory", static_cast<double>(si.totalram) * si.mem_unit / 1024.0},
               {"memory_units", "kB"}}},
             {"sd_info", json::object()},
             {"distribution",
              {{"name", os_release("PRETTY_NAME")},
               {"id", os_release("ID")},
               {"version", version},
               {"version_parts", {{"major", version}, {"minor", ""}, {"build_number", ""}}},
               {"like", os_release("ID_LIKE")},
               {"codename", os_release("VERSION_CODENAME")}}},
             {"available_services", json::array()},
             {"instance_ids", {{"moonraker", "feedloopd"}, {"klipper", "feedloopd"}}},
             {"service_state", json::object()},
             {"virtualization", {{"virt_type", "none"}, {"virt_identifier", "none"}}},
             {"network", json::object()},
             {"canbus", json::object()}}}});
  };
  m["machine.proc_stats"] = [this, ok](uint64_t, const json&, Done d) {
    json s = proc_stats(wall_s());
    s["moonraker_stats"] = json::array({s["moonraker_stats"]});
    s["throttled_state"] = {{"bits", 0}, {"flags", json::array()}};
    ok(d, s);
  };
  // Access (Moonraker's authorization component): a request that reaches the API has passed the
  // access check (web/access.hpp: a trusted address or the API key), so the user is Moonraker's
  // trusted user. Fluidd asks at load and, without a user, fetches a oneshot token before each
  // upload (access.oneshot_token, which feedloop does not have: its uploads then failed).
  m["access.get_user"] = [ok](uint64_t, const json&, Done d) {
    ok(d, {{"username", "_TRUSTED_USER_"}, {"source", "moonraker"}, {"created_on", wall_s()}});
  };
  m["access.info"] = [ok](uint64_t, const json&, Done d) {
    ok(d, {{"default_source", "moonraker"},
           {"available_sources", json::array({"moonraker"})},
           {"login_required", false},
           {"trusted", true}});
  };
  m["access.users.list"] = [ok](uint64_t, const json&, Done d) {
    ok(d, {{"users", json::array()}});
  };
  // Moonraker's oneshot token authorizes one request of a logged-in user (downloads, uploads).
  // feedloop has no logins: the request that carries it must pass the access check by its address
  // or the API key anyway, so the token is a random string that authorizes nothing by itself.
  m["access.oneshot_token"] = [ok](uint64_t, const json&, Done d) {
    static std::mt19937_64 rng{std::random_device{}()};
    char buf[33];
    std::snprintf(buf, sizeof buf, "%016llx%016llx", static_cast<unsigned long long>(rng()),
                  static_cast<unsigned long long>(rng()));
    ok(d, std::string(buf));
  };
  // The API key is not handed out over the API (Moonraker shows it to logged-in users).
  m["access.get_api_key"] = [ok](uint64_t, const json&, Done d) { ok(d, ""); };
  // Components feedloop advertises with nothing in them.
  m["server.webcams.list"] = [ok](uint64_t, const json&, Done d) {
    ok(d, {{"webcams", json::array()}});
  };
  m["server.job_queue.status"] = [ok](uint64_t, const json&, Done d) {
    ok(d, {{"queued_jobs", json::array()}, {"queue_state", "ready"}});
  };
  m["server.announcements.list"] = [ok](uint64_t, const json&, Done d) {
    ok(d, {{"entries", json::array()}, {"feeds", json::array()}});
  };
  // feedloop's own: the last calibration report (web/calibration_report.hpp) for our page.
  m["server.feedloop.calibration_report"] = [this, ok](uint64_t, const json&, Done d) {
    if (options_.calibration_dir.empty())
      return ok(d, {{"found", false}, {"dir", ""}, {"message", "web.calibration_dir is not set"}});
    ok(d, latest_calibration_report(options_.calibration_dir));
  };
  // feedloop's own: the tracking-error points for our page (from: the first point wanted).
  m["server.feedloop.tracking_points"] = [this, ok, fail](uint64_t, const json& p, Done d) {
    Params pp{p};
    const auto from = static_cast<size_t>(std::max<int64_t>(0, pp.integer("from", 0)));
    const auto limit =
        static_cast<size_t>(std::clamp<int64_t>(pp.integer("limit", 20000), 1, 100000));
    if (!pp.error.empty()) return fail(d, pp.error);
    ok(d, telemetry_.points(from, limit));
  };
}

}  // namespace feedloop::web
