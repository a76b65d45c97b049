// The daemon's side of the web server (web/printer_backend.hpp): printer facts, G-code from the
// console, and print jobs from the web's gcodes folder.
//
// A print job reads its file line by line and submits each command through the daemon's
// submit() as the web's internal client, so print ownership, the machine's queue (flow control)
// and the flight recorder apply as for a host on the socket. At most kJobInFlight lines are
// waiting for the machine at once, and no line is read while the machine holds more than
// kJobAheadS of planned motion (or kJobQueueDepth commands). PAUSE stops feeding lines (the moves
// already queued finish, as Klipper's PAUSE lets the lookahead queue run out); RESUME feeds again;
// CANCEL_PRINT stops for good. The job is complete once the file is read and the machine is idle.
#include <spdlog/spdlog.h>

#include <filesystem>
#include <fstream>

#include "config/config.hpp"
#include "daemon/daemon.hpp"
#include "gcode/parser.hpp"
#include "web/database.hpp"
#include "web/file_store.hpp"
#include "web/http_server.hpp"
#include "web/moonraker_api.hpp"

namespace feedloop::daemon {

namespace asio = boost::asio;
using nlohmann::json;

namespace {
constexpr int kJobInFlight = 4;
constexpr uint32_t kJobQueueDepth = 8;  // commands waiting in the machine's queue
constexpr double kJobAheadS = 2.0;      // planned motion not yet executed
constexpr const char* kWebVersion = "0.1.0";

// The web's own client: it has no connection; replies go to the web API through callbacks.
class InternalSession final : public ClientSession {
 public:
  InternalSession(uint64_t id, std::string name) : ClientSession(id, std::move(name)) {}
  void start() override {}

 protected:
  void do_write(const std::string&) override {}
  void do_close() override {}
  void do_read() override {}
};
}  // namespace

Status Daemon::open_web() {
  if (!cfg_.web.enabled) return Status::Ok();
  const config::PathVars vars = config::path_vars_from_environment();
  auto files_dir = config::expand_path(cfg_.web.files_dir, vars);
  auto db_path = config::expand_path(cfg_.web.database, vars);
  if (!files_dir) return Error{"web.files_dir: " + files_dir.error().message};
  if (!db_path) return Error{"web.database: " + db_path.error().message};
  auto files = web::FileStore::open(*files_dir);
  if (!files) return files.error();
  std::error_code ec;
  std::filesystem::create_directories(std::filesystem::path(*db_path).parent_path(), ec);
  auto db = web::Database::open(*db_path);
  if (!db) return db.error();
  auto access = web::AccessPolicy::create(cfg_.web.trusted_clients, cfg_.web.api_key);
  if (!access) return access.error();
  web_files_ = std::make_unique<web::FileStore>(std::move(*files));
  web_db_ = std::move(*db);
  web::MoonrakerApi::Options ao;
  ao.version = kWebVersion;
  ao.host = cfg_.web.address;
  ao.port = cfg_.web.port;
  web_api_ = std::make_unique<web::MoonrakerApi>(*this, *web_files_, *web_db_, ao);
  web::ServerOptions so;
  so.address = cfg_.web.address;
  so.port = cfg_.web.port;
  so.ui_dir = cfg_.web.ui_dir;
  so.page_dir = cfg_.web.page_dir;
  so.uplot_dir = cfg_.web.uplot_dir;
  web_server_ = std::make_unique<web::HttpServer>(io_, *web_api_, std::move(*access), so);
  if (Status s = web_server_->start(); !s) return s;
  // The internal client the web's commands and jobs run as.
  const uint64_t id = next_client_id_++;
  Client& c = clients_[id];
  c.id = id;
  c.session = std::make_shared<InternalSession>(id, "web");
  c.kind = Kind::kJson;
  c.last_progress_ns = clock_.now_ns();
  web_client_id_ = id;
  web_job_ = std::make_unique<WebJob>();
  spdlog::info(
      "web: http://{}:{}/ (UI: {}), feedloop's page at /server/feedloop/page/, files in {}",
      cfg_.web.address, web_server_->port(), cfg_.web.ui_dir.empty() ? "none" : cfg_.web.ui_dir,
      *files_dir);
  return Status::Ok();
}

void Daemon::close_web() {
  if (web_server_) web_server_->stop();
}

uint16_t Daemon::web_port() const {
  return web_server_ ? web_server_->port() : 0;
}

web::PrinterInfo Daemon::printer_info() const {
  web::PrinterInfo p;
  p.name = cfg_.name;
  p.kinematics = cfg_.kinematics == config::Kinematics::delta    ? "delta"
                 : cfg_.kinematics == config::Kinematics::corexy ? "corexy"
                                                                 : "cartesian";
  p.version = kWebVersion;
  const char* names[3] = {"x", "y", "z"};
  for (int i = 0; i < 3; ++i)
    if (const config::AxisConfig* a = cfg_.axis(names[i])) {
      p.axis_min_mm[i] = a->min_mm;
      p.axis_max_mm[i] = a->max_mm;
    }
  p.max_velocity_mm_s = cfg_.planner.max_velocity_mm_s;
  p.max_accel_mm_s2 = cfg_.planner.max_accel_mm_s2;
  p.square_corner_velocity_mm_s = cfg_.planner.square_corner_velocity_mm_s;
  p.min_cruise_ratio = cfg_.planner.min_cruise_ratio;
  p.servo_period_s = 1.0 / cfg_.servo.rate_hz;
  p.simulated = cfg_.uses_simulator();
  return p;
}

engine::MachineStatus Daemon::machine_status() const {
  return machine_->status();
}
engine::ServoStatus Daemon::servo_status() const {
  return machine_->servo_status();
}

web::JobStatus Daemon::job_status() const {
  web::JobStatus s;
  if (!web_job_) return s;
  s.state = web_job_->state;
  s.filename = web_job_->filename;
  s.file_position = web_job_->position;
  s.file_size = web_job_->size;
  s.message = web_job_->message;
  if (web_job_->start_ns != 0) {
    const int64_t end = web_job_->end_ns != 0 ? web_job_->end_ns : clock_.now_ns();
    const int64_t paused =
        web_job_->paused_total_ns + (web_job_->paused_since_ns != 0 ? end - web_job_->paused_since_ns : 0);
    s.total_duration_s = seconds_from_ns(end - web_job_->start_ns);
    s.print_duration_s = seconds_from_ns(end - web_job_->start_ns - paused);
  }
  return s;
}

void Daemon::run_gcode(std::string script,
                       std::function<void(bool ok, std::string response)> done) {
  Client* c = find_client(web_client_id_);
  if (!c) return done(false, "the web client is gone");
  run_script(*c->session, std::move(script), [done](json result, std::string error) {
    if (!error.empty()) return done(false, error);
    bool ok = true;
    std::string response;
    for (const json& r : result.value("results", json::array())) {
      if (!r.value("ok", false)) {
        ok = false;
        response += r.value("error", std::string("failed"));
        response += '\n';
      } else if (r.contains("reply")) {
        response += r["reply"].get<std::string>();
        response += '\n';
      }
    }
    if (!response.empty()) response.pop_back();
    done(ok, response);
  });
}

std::string Daemon::start_job(const std::string& path, const std::string& filename) {
  if (!web_job_) return "the web server is not running";
  if (web_job_->state == web::JobState::printing || web_job_->state == web::JobState::paused)
    return "a print is already running (" + web_job_->filename + ")";
  if (owner_ != 0 && owner_ != web_client_id_) {
    const Client* o = find_client(owner_);
    return "busy: the print is owned by " +
           (o ? o->session->name() : std::string("another client"));
  }
  auto in = std::make_unique<std::ifstream>(path, std::ios::binary);
  if (!*in) return "cannot open '" + filename + "'";
  std::error_code ec;
  const uintmax_t size = std::filesystem::file_size(path, ec);
  *web_job_ = WebJob{};
  web_job_->state = web::JobState::printing;
  web_job_->filename = filename;
  web_job_->in = std::move(in);
  web_job_->size = ec ? 0 : size;
  web_job_->start_ns = clock_.now_ns();
  spdlog::info("web: printing {} ({} bytes)", filename, web_job_->size);
  feed_job();
  return {};
}

std::string Daemon::pause_job() {
  if (!web_job_ || web_job_->state != web::JobState::printing) return "Print is not in progress";
  web_job_->state = web::JobState::paused;
  web_job_->paused_since_ns = clock_.now_ns();
  spdlog::info("web: print paused at byte {} of {}", web_job_->position, web_job_->size);
  return {};
}

std::string Daemon::resume_job() {
  if (!web_job_ || web_job_->state != web::JobState::paused) return "Print is not paused, resume aborted";
  web_job_->paused_total_ns += clock_.now_ns() - web_job_->paused_since_ns;
  web_job_->paused_since_ns = 0;
  web_job_->state = web::JobState::printing;
  spdlog::info("web: print resumed");
  feed_job();
  return {};
}

std::string Daemon::cancel_job() {
  if (!web_job_ || (web_job_->state != web::JobState::printing && web_job_->state != web::JobState::paused))
    return "No print in progress";
  end_job(web::JobState::cancelled, "");
  return {};
}

void Daemon::restart() {
  reload_requested_ = true;
  spdlog::info("web: restart requested: the machine is rebuilt when idle");
}

void Daemon::end_job(web::JobState state, const std::string& message) {
  if (web_job_->paused_since_ns != 0) {
    web_job_->paused_total_ns += clock_.now_ns() - web_job_->paused_since_ns;
    web_job_->paused_since_ns = 0;
  }
  web_job_->state = state;
  web_job_->message = message;
  web_job_->end_ns = clock_.now_ns();
  web_job_->in.reset();
  if (state == web::JobState::error)
    spdlog::error("web: print {} failed: {}", web_job_->filename, message);
  else
    spdlog::info("web: print {} {}", web_job_->filename, web::to_string(state));
}

void Daemon::feed_job() {
  if (!web_job_ || web_job_->state != web::JobState::printing) return;
  Client* c = find_client(web_client_id_);
  if (!c) return;
  std::string line;
  while (!web_job_->eof && web_job_->in_flight < kJobInFlight && !c->parked) {
    // Read ahead of the machine by a bounded amount, as Klipper's virtual_sdcard does (its
    // lookahead holds about 2 s of moves): a pause then stops the motion within that.
    const engine::MachineStatus ms = machine_->status();
    if (ms.queue_depth >= kJobQueueDepth ||
        (ms.moving && ms.planned_until_s - ms.print_time_s > kJobAheadS))
      break;
    if (!std::getline(*web_job_->in, line)) {
      web_job_->eof = true;
      web_job_->position = web_job_->size;
      break;
    }
    ++web_job_->line;
    const std::streamoff at = web_job_->in->tellg();
    if (at >= 0) web_job_->position = static_cast<uint64_t>(at);
    if (const size_t semi = line.find(';'); semi != std::string::npos) line.resize(semi);
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.find_first_not_of(" \t") == std::string::npos) continue;
    auto cmd =
        gcode::parse_line(line, SourceLocation{web_job_->filename, static_cast<int>(web_job_->line), 0});
    if (!cmd) return end_job(web::JobState::error, cmd.error().to_string());
    std::string answer;
    if (answer_query(*cmd, answer)) continue;
    ++web_job_->in_flight;
    WebJob* job = web_job_.get();
    const int64_t started = web_job_->start_ns;
    std::string refused =
        submit(*c, *cmd, line, recorder::GcodeSource::api, [this, job, started](const Status& st) {
          if (web_job_.get() != job || job->start_ns != started) return;  // a later job
          --job->in_flight;
          if (!st && (job->state == web::JobState::printing || job->state == web::JobState::paused))
            return end_job(web::JobState::error, st.error().to_string());
          feed_job();
        });
    if (!refused.empty()) {
      --web_job_->in_flight;
      return end_job(web::JobState::error, refused);
    }
  }
  if (web_job_->eof && web_job_->in_flight == 0 && !c->parked && machine_->idle())
    end_job(web::JobState::complete, "");
}

}  // namespace feedloop::daemon
