// Moonraker's API (https://moonraker.readthedocs.io/en/latest/web_api/) as Mainsail and Fluidd use
// it: JSON-RPC 2.0 over the WebSocket (single requests and batches), the same methods over HTTP
// routes, and the notifications (notify_status_update, notify_gcode_response,
// notify_proc_stat_update every second, notify_filelist_changed, notify_history_changed,
// notify_klippy_ready/shutdown). Klipper's printer objects are built from the printer backend's
// snapshot (web/printer_objects.cpp); feedloop's own objects sit beside them (feedloop_servo,
// feedloop_links, feedloop_tracking). Transport-free: the server (web/http_server.hpp) feeds it
// text and delivers what it sends; tests drive it directly. I/O thread only.
//
// Errors follow Moonraker: an unknown method gets {"code":-32601,"message":"Method not found"},
// a malformed message -32700/-32600, a request that fails its check 400 (404 for a missing
// file, namespace or key) with a message saying which parameter. No request ends the daemon.
#pragma once

#include <nlohmann/json.hpp>

#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <string_view>

#include "web/database.hpp"
#include "web/file_store.hpp"
#include "web/printer_backend.hpp"
#include "web/telemetry.hpp"

namespace feedloop::web {

struct HttpRequest {
  std::string method;  // GET, POST, DELETE
  std::string path;    // without the query
  std::map<std::string, std::string> query;
  std::string content_type;
  std::string body;          // an ordinary request's body
  std::string_view spooled;  // an upload's body, mapped from its temporary file (web/spooled_body)
  std::string_view bytes() const { return spooled.empty() ? std::string_view(body) : spooled; }
};

struct HttpReply {
  int status = 200;
  std::string content_type = "application/json";
  std::string body;
  std::string file_path;  // non-empty: send this file instead of body
};

class MoonrakerApi {
 public:
  struct Options {
    std::string version = "0.1.0";
    std::string host = "127.0.0.1";
    int port = 7125;
    double status_period_s = 0.25;         // notify_status_update at most this often
    size_t temperature_store_size = 1200;  // one sample per second (Moonraker's default)
    size_t gcode_store_size = 1000;
    // server.feedloop.calibration_report: the newest `feedloop ident fit` report here (empty:
    // none configured).
    std::string calibration_dir;
  };
  // Sends one text frame; returns false when the connection was dropped (a slow reader).
  using Send = std::function<bool(std::shared_ptr<const std::string>)>;

  MoonrakerApi(PrinterBackend& printer, FileStore& files, Database& db, Options options);
  ~MoonrakerApi();

  uint64_t open_connection(Send send);
  void close_connection(uint64_t id);
  size_t connections() const { return conns_.size(); }
  // One WebSocket text message: a request, a notification or a batch (array).
  void on_message(uint64_t conn, std::string_view text);

  // The HTTP API routes (/server/..., /printer/..., /machine/..., /access/...).
  static bool is_api_path(std::string_view path);
  // The routes whose body is a file upload (spooled to disk by the server, not held in memory).
  static bool is_upload_path(std::string_view path) {
    return path == "/server/files/upload" || path == "/api/files/local";
  }
  void on_http(const HttpRequest& req, std::function<void(HttpReply)> done);

  // Periodic (the server calls it every 50-100 ms): status notifications, proc stats, the
  // temperature store, history and telemetry sampling.
  void tick(double now_s);

  // A console line from elsewhere (another channel's command): notify_gcode_response and the
  // G-code store, as Moonraker relays every response Klipper sends.
  void console_echo(const std::string& text) { gcode_response(text); }

  // Every printer object with all its fields, as printer.objects.query returns them.
  nlohmann::json all_objects() const;
  const TrackingTelemetry& telemetry() const { return telemetry_; }

  // Counters for tests and the load benchmark.
  uint64_t requests() const { return requests_; }
  uint64_t notifications_sent() const { return notifications_sent_; }

 private:
  struct Connection;
  using Done = std::function<void(nlohmann::json result, int code, std::string error)>;
  using Handler = std::function<void(uint64_t conn, const nlohmann::json& params, Done done)>;

  void register_methods();
  void handle(uint64_t conn, const nlohmann::json& request,
              std::function<void(nlohmann::json reply)> reply);
  void call(uint64_t conn, const std::string& method, const nlohmann::json& params, Done done);
  void send(uint64_t conn, std::shared_ptr<const std::string> text);
  void broadcast(const std::string& method, nlohmann::json params);
  void gcode_response(const std::string& text);
  void run_script(std::vector<std::string> lines, size_t next, Done done);
  void upload(const HttpRequest& req, std::function<void(HttpReply)> done);
  // A multipart upload stored (and its print started when the form asks): what both
  // /server/files/upload and OctoPrint's /api/files/local answer from.
  struct StoredUpload {
    nlohmann::json item;  // {path, root, modified, size, permissions}
    std::string rel;      // relative to its root
    bool print_started = false;
  };
  // `root`: the root to store in whatever the form says ("": the form's "root", else gcodes).
  Result<StoredUpload> store_upload(const HttpRequest& req, const std::string& root = {});
  // OctoPrint's REST API as slicers use it (web/octoprint_compat.cpp).
  void octoprint(const HttpRequest& req, std::function<void(HttpReply)> done);
  void track_jobs(double now_s);
  nlohmann::json filtered(const nlohmann::json& all, const nlohmann::json& wanted) const;
  nlohmann::json proc_stats(double now_s);
  double eventtime() const;

  PrinterBackend& printer_;
  FileStore& files_;
  Database& db_;
  Options options_;
  std::map<std::string, Handler> methods_;
  std::map<uint64_t, std::unique_ptr<Connection>> conns_;
  uint64_t next_conn_ = 1;
  double now_s_ = 0.0, last_status_s_ = -1.0, last_proc_s_ = -1.0, last_temp_s_ = -1.0,
         start_s_ = -1.0;
  std::string last_webhooks_state_ = "ready";
  struct TempSeries {
    std::deque<double> temps, targets, powers;
  };
  std::map<std::string, TempSeries> temps_;
  struct GcodeEntry {
    std::string message;
    double time;
    std::string type;
  };
  std::deque<GcodeEntry> gcode_store_;
  TrackingTelemetry telemetry_;
  // History: the job being printed (database row) and the state last seen.
  int64_t job_row_ = -1;
  nlohmann::json job_;
  JobState last_job_state_ = JobState::standby;
  std::string last_job_file_;
  // /proc samples for cpu usage.
  double last_cpu_s_ = 0.0, last_cpu_wall_s_ = 0.0, cpu_usage_ = 0.0;
  uint64_t requests_ = 0, notifications_sent_ = 0;
};

}  // namespace feedloop::web
