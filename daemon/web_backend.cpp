// The daemon's side of the web server (web/printer_backend.hpp): printer facts, G-code from the
// console, and print jobs. There is one print job path: the web's gcodes root is the job folder
// (jobs.directory) and printer.print.start/pause/resume/cancel (and the PAUSE, RESUME,
// CANCEL_PRINT and SDCARD_PRINT_FILE macros) act on the daemon's print job (daemon/print_job.hpp),
// the same object that M23/M24/M25/M32/M524 and the JSON API's job.* drive. print_stats shows
// that job whoever started it. Console lines run as the web's internal client through the same
// submit() as a host on the socket (print ownership, flow control, the flight recorder).
#include <spdlog/spdlog.h>

#include <cctype>
#include <filesystem>

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
  auto calibration_dir = config::expand_path(cfg_.web.calibration_dir, vars);
  if (!calibration_dir) return Error{"web.calibration_dir: " + calibration_dir.error().message};
  // The gcodes root is the job folder: an uploaded file is the one M23/M32 and job.start print.
  auto files =
      web::FileStore::open(*files_dir, job_files_ ? job_files_->directory() : std::string());
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
  ao.calibration_dir = *calibration_dir;
  web_api_ = std::make_unique<web::MoonrakerApi>(*this, *web_files_, *web_db_, ao);
  web::ServerOptions so;
  so.address = cfg_.web.address;
  so.port = cfg_.web.port;
  so.ui_dir = cfg_.web.ui_dir;
  so.page_dir = cfg_.web.page_dir;
  so.uplot_dir = cfg_.web.uplot_dir;
  so.upload_dir = web_files_->root_dir("gcodes");  // the uploads' own file system
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
  p.min_extrude_temp_c = cfg_.extruder.min_extrude_temp;
  p.nozzle_diameter_mm = cfg_.extruder.nozzle_diameter;
  p.filament_diameter_mm = cfg_.extruder.filament_diameter;
  return p;
}

engine::MachineStatus Daemon::machine_status() const {
  return machine_->status();
}
engine::ServoStatus Daemon::servo_status() const {
  return machine_->servo_status();
}

// print_stats / virtual_sdcard from the daemon's one print job (daemon/print_job.hpp): the job
// M23/M24/M32, the JSON API's job.* and the web all start, pause, resume and cancel. Klipper's
// states (klippy/extras/print_stats.py): its PAUSE shows "paused" at once while the toolhead
// still parks, so kPausing is paused; resuming and cancelling still move for the job: printing.
// Without a job, a print that a client streams over the socket, the pty or the JSON API (it owns
// the print) shows as printing with no file name and the channel in `message`.
web::JobStatus Daemon::job_status() const {
  web::JobStatus s;
  const JobStatus j = print_job_status();
  switch (j.state) {
    case JobState::kIdle:
    case JobState::kReady:
      s.state = web::JobState::standby;
      break;
    case JobState::kPrinting:
    case JobState::kResuming:
    case JobState::kCancelling:
      s.state = web::JobState::printing;
      break;
    case JobState::kPausing:
    case JobState::kPaused:
      s.state = web::JobState::paused;
      break;
    case JobState::kComplete:
      s.state = web::JobState::complete;
      break;
    case JobState::kCancelled:
      s.state = web::JobState::cancelled;
      break;
    case JobState::kError:
      s.state = web::JobState::error;
      break;
  }
  if (j.state != JobState::kIdle) {
    s.filename = j.file;
    s.file_position = j.bytes_submitted;
    s.file_size = j.size_bytes;
    s.total_duration_s = j.elapsed_s;
    s.print_duration_s = std::max(0.0, j.elapsed_s - j.paused_s);
    s.filament_used_mm = j.filament_used_mm;
    if (j.state == JobState::kError) s.message = j.message;
  }
  const bool job_active = job_ && job_->active();
  if (!job_active && owner_ != 0 && owner_ != kJobOwner && owner_ != web_client_id_) {
    // A streamed print: as long as the client owns the print (ownership_idle_s after its last
    // command once the machine is idle, docs/jobs.md).
    s = web::JobStatus{};
    s.state = web::JobState::printing;
    s.message = "streamed by " + owner_name();
    s.total_duration_s = s.print_duration_s = seconds_from_ns(clock_.now_ns() - owner_since_ns_);
  }
  // A streaming host's M0 / M600 waits for the user: paused, so Mainsail and Fluidd offer their
  // resume button (resume_job() answers it as M108 would).
  if (!job_active && user_waiting()) {
    s.state = web::JobState::paused;
    if (s.message.empty()) s.message = display_message_;
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

// The web's gcodes root is the job folder (open_web), so `filename` is a job file's name. The
// web client is the requester: a print started right after a move typed in the console (the web
// owns the print for ownership_idle_s) is not refused as busy.
std::string Daemon::start_job(const std::string& /*path*/, const std::string& filename) {
  Status st = job_start(filename, web_client_id_);
  snapshot_.stale = true;
  return st ? std::string() : st.error().to_string();
}

std::string Daemon::job_name_error(const std::string& filename) const {
  const Status st = JobFiles::validate_path(filename);
  return st ? std::string() : st.error().to_string();
}

std::string Daemon::pause_job() {
  if (!job_ || !job_->active()) return "Print is not in progress";  // Klipper's PAUSE text
  Status st = job_pause();
  snapshot_.stale = true;
  return st ? std::string() : st.error().to_string();
}

std::string Daemon::resume_job() {
  const bool job_paused =
      job_ && (job_->state() == JobState::kPaused || job_->state() == JobState::kPausing);
  if (!job_paused && user_waiting()) {  // a streaming host's M0 / M600: the web's answer is M108's
    on_user_answer();
    snapshot_.stale = true;
    return {};
  }
  if (!job_paused) return "Print is not paused, resume aborted";  // Klipper's RESUME text
  Status st = job_resume(web_client_id_);
  snapshot_.stale = true;
  return st ? std::string() : st.error().to_string();
}

std::string Daemon::cancel_job() {
  if (!job_ || !job_->active()) return "No print in progress";
  Status st = job_cancel();
  snapshot_.stale = true;
  return st ? std::string() : st.error().to_string();
}

std::string Daemon::reset_job() {
  if (!job_) return {};
  Status st = job_->clear();
  snapshot_.stale = true;
  return st ? std::string() : st.error().to_string();
}

// Moonraker's console shows every G-code response Klipper sends, whoever caused it; here, a line
// another channel sends (socket, pty, JSON API) is shown as "<client>: <line>", without its N
// number and checksum. Moves are left out and at most kEchoPerSecond lines a second are shown
// (then one line says how many were left out): a host streaming a print must not flood the
// browsers (each WebSocket's send queue is bounded, docs/web.md).
void Daemon::echo_to_web(const Client& c, std::string_view line, const gcode::Command& cmd) {
  constexpr int kEchoPerSecond = 20;
  if (!web_api_ || c.id == web_client_id_) return;
  if (cmd.letter == 'G' && cmd.code <= 3) return;
  const int64_t now = clock_.now_ns();
  if (now - echo_window_ns_ >= kNsPerS) {
    if (echo_dropped_ > 0)
      web_api_->console_echo("// " + std::to_string(echo_dropped_) +
                             " lines from other channels not shown");
    echo_window_ns_ = now;
    echo_in_window_ = 0;
    echo_dropped_ = 0;
  }
  if (++echo_in_window_ > kEchoPerSecond) {
    ++echo_dropped_;
    return;
  }
  // "N12 M104 S200*87" -> "M104 S200"
  while (!line.empty() && (line.front() == ' ' || line.front() == '\t')) line.remove_prefix(1);
  if (!line.empty() && (line.front() == 'N' || line.front() == 'n')) {
    size_t i = 1;
    while (i < line.size() && (std::isdigit(static_cast<unsigned char>(line[i])) || line[i] == '-'))
      ++i;
    if (i > 1) line.remove_prefix(i);
    while (!line.empty() && line.front() == ' ') line.remove_prefix(1);
  }
  if (const size_t star = line.rfind('*');
      star != std::string_view::npos && star + 1 < line.size() &&
      line.find_first_not_of("0123456789", star + 1) == std::string_view::npos)
    line = line.substr(0, star);  // the checksum
  while (!line.empty() && (line.back() == ' ' || line.back() == '\r')) line.remove_suffix(1);
  web_api_->console_echo(c.session->name() + ": " + std::string(line));
}

void Daemon::restart() {
  reload_requested_ = true;
  spdlog::info("web: restart requested: the machine is rebuilt when idle");
}

}  // namespace feedloop::daemon
