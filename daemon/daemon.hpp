// feedloopd's assembly: the machine (planner + servo threads), the client channels on one
// Asio I/O thread, signals turned into commands (SIGTERM/SIGINT: shutdown, SIGHUP: reload the
// config when idle), print ownership, and systemd notifications.
//
// Print ownership: a client owns the print from its first machine command until it disconnects
// or has been idle (nothing queued, machine idle) for `ownership_idle_s`. Machine commands from
// other clients get "Error:busy" while someone owns it; queries (M105, M114, M115, JSON status)
// are answered for everyone. A client that does not read its replies is disconnected; nothing
// it does can stall motion. Client work is bounded (client_session.hpp: input queue, lines per
// turn, a rate limit with throttling and then a drop) and `status` comes from a snapshot.
//
// Flight recorder (docs/recorder.md): with `recorder.enabled` every print is recorded. A print
// starts when a client takes ownership and ends when the ownership is released and the machine is
// idle (or at shutdown / reload). The G-code lines submitted to the machine are recorded on the
// I/O thread with their time on the machine clock; the engine records moves, step runs, encoder
// samples, anchors and events (recorder::EngineRecording); the recorder thread writes the file.
#pragma once

#include <boost/asio.hpp>

#include <deque>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "config/machine_config.hpp"
#include "core/clock.hpp"
#include "core/result.hpp"
#include "daemon/client_session.hpp"
#include "daemon/job_files.hpp"
#include "daemon/json_api.hpp"
#include "daemon/listeners.hpp"
#include "daemon/print_job.hpp"
#include "daemon/repeat_filter.hpp"
#include "daemon/watchdog.hpp"
#include "engine/machine.hpp"
#include "gcode/host_protocol.hpp"
#include "recorder/engine_recording.hpp"
#include "recorder/recorder.hpp"
#include "web/printer_backend.hpp"

namespace feedloop::web {
class Database;
class FileStore;
class HttpServer;
class MoonrakerApi;
}  // namespace feedloop::web

namespace feedloop::daemon {

struct DaemonOptions {
  std::string config_path;  // empty: the embedded default config
  double ownership_idle_s = 5.0;
  // Simulated printers only: the machine runs in virtual time, as fast as the CPU allows (the
  // same pipeline; for tests and demos). Channels and timers stay in real time.
  bool virtual_time = false;
  // Client I/O (client_session.hpp): JSON API requests, and Marlin lines that do not go to the
  // machine (queries, errors, refusals; machine commands are paced by the machine's queue).
  InputLimits api_limits{200.0, 200.0, 5.0, 16};
  InputLimits marlin_limits{1000.0, 1000.0, 5.0, 16};
  // `status` replies and notifications come from a snapshot at most this old (ms).
  int status_period_ms = 10;
  // The calibration overlay laid over the config (daemon/config_source.hpp) at every reload;
  // empty: none. Not required: a missing file is no calibration (the default path).
  std::string calibration_path;
  bool calibration_required = false;
};

// Print jobs (daemon/print_job.hpp, docs/jobs.md): the daemon reads a file of the job folder into
// the same submit path the clients use; while the job sends commands it owns the print (its own
// owner id, kJobOwner), so the print goes on when the client that started it disconnects.
class Daemon final : public JsonApiBackend, public web::PrinterBackend, private JobSink {
 public:
  Daemon(config::MachineConfig cfg, DaemonOptions options);
  ~Daemon() override;
  // The calibration overlay `cfg` carries (config_source.hpp), for `info`; before start.
  void set_calibration_applied(std::string path) { calibration_applied_ = std::move(path); }

  // Starts the machine and opens every channel. On error nothing is left running.
  Status start();
  // Runs the I/O loop until shutdown; returns the process exit code.
  int run();
  // Any thread: stop motion safely, close channels, return from run().
  void request_shutdown(const std::string& why);

  boost::asio::io_context& io() { return io_; }
  const std::string& socket_path() const { return socket_path_; }
  const std::string& api_socket_path() const { return api_socket_path_; }
  const std::string& pty_link() const { return pty_link_; }
  uint64_t reloads() const { return reloads_; }
  // The flight recorder (nullptr: disabled or could not be created); tests read its stats.
  const recorder::Recorder* flight_recorder() const { return recorder_.get(); }
  // Logs of the prints recorded since start, in order (each print: its parts). I/O thread.
  const std::vector<std::string>& recorded_logs() const { return recorded_logs_; }

  // JsonApiBackend
  nlohmann::json info() const override;
  nlohmann::json status() const override;
  std::shared_ptr<const std::string> status_text() override;
  void run_script(ClientSession& client, std::string script,
                  std::function<void(nlohmann::json, std::string)> done) override;
  void emergency_stop(const std::string& reason) override;
  std::optional<MethodResult> call_method(ClientSession& client, const std::string& method,
                                          const nlohmann::json& params) override;

  // The job controller's interface for the web API (web/) and tests: the calls the JSON API's
  // files.* / job.* methods make. `requester`: the client id asking (0: none, e.g. the web API).
  // I/O thread only.
  Result<std::vector<JobFileInfo>> job_files_list() const;
  Result<JobFileInfo> job_file_upload(const std::string& name, std::string_view content);
  Status job_file_delete(const std::string& name);
  Status job_start(const std::string& name, uint64_t requester = 0);
  Status job_pause();
  Status job_resume(uint64_t requester = 0);
  Status job_cancel();
  JobStatus print_job_status() const;
  nlohmann::json job_status_json() const;

  // The narrow heater hook (the heaters' module connects here): a heater's target, and every
  // heater off. Today they set the simulated heaters' targets through the machine's queue, in
  // order behind the commands already in it. I/O thread.
  enum class Heater { kHotend, kBed };
  void set_heater_target(Heater heater, double target_c);
  void all_heaters_off() override;
  // The job's cancel at once (JobSink::cancel_motion): engine::Machine::flush with the heaters off.
  void cancel_motion() override;

  // web::PrinterBackend (daemon/web_backend.cpp): the web server's view of the printer. Print
  // jobs are the daemon's one print job (job_); heaters and fans are the machine's status.
  web::PrinterInfo printer_info() const override;
  engine::MachineStatus machine_status() const override;
  engine::ServoStatus servo_status() const override;
  web::JobStatus job_status() const override;
  planner::ObjectLabels object_labels() const override { return machine_->object_labels(); }
  bool has_object_labels() const override { return !machine_->object_labels().empty(); }
  void run_gcode(std::string script, std::function<void(bool ok, std::string response)> done) override;
  std::string start_job(const std::string& path, const std::string& filename) override;
  std::string job_name_error(const std::string& filename) const override;
  std::string pause_job() override;
  std::string resume_job() override;
  std::string cancel_job() override;
  std::string reset_job() override;
  void restart() override;
  // The web server's port (0: not running); tests use port 0 and read it here.
  uint16_t web_port() const;
  const web::MoonrakerApi* web_api() const { return web_api_.get(); }
  const web::HttpServer* web_server() const { return web_server_.get(); }

 private:
  static constexpr uint64_t kJobOwner = UINT64_MAX;  // the owner id of a print job
  enum class Kind { kMarlin, kJson };
  struct Parked {
    uint64_t ticket;
    gcode::Command command;
  };
  // A Marlin line's answer, kept in arrival order: Marlin answers every line in order, and hosts
  // pair each `ok` with the oldest line they sent. A query waits behind the commands before it.
  struct ReplySlot {
    bool ready = false;
    bool is_query = false;
    gcode::Command query;  // is_query: answered when it reaches the front
    std::string text;      // ready: the reply lines, without the last '\n'
  };
  // Marlin's M0 / M1 (without P or S) and M600 from a Marlin client (daemon_user_wait.cpp): the
  // machine finishes the client's commands (M600 then parks the head), the client's later lines
  // wait, and M108 or M876 from any client ends the wait (M600 then returns the head).
  struct UserWait {
    std::shared_ptr<ReplySlot> slot;  // the stop's own answer, sent when the wait ends
    std::string message;
    bool filament_change = false;           // M600
    bool waiting = false;                   // the machine has stopped (and parked): the user's turn
    bool retracted = false;                 // M600: the park pulled the filament back
    double parked_from_mm[4] = {0, 0, 0, 0};  // M600: where the park found the head (X Y Z E)
    std::vector<std::string> restore_lines;   // M600: the host's G90 / G91, M82 / M83, F and G20
  };
  struct Client {
    uint64_t id = 0;
    std::shared_ptr<ClientSession> session;
    Kind kind = Kind::kMarlin;
    std::unique_ptr<gcode::HostProtocol> protocol;  // Marlin channels
    Subscription subscription;                      // JSON channels
    int64_t next_status_ns = 0;
    std::deque<std::string> backlog;  // lines received while a command is parked
    std::optional<Parked> parked;     // a command waiting for room in the machine queue
    size_t in_flight = 0;             // submitted, not yet done
    int64_t last_progress_ns = 0;     // last ok, or last keepalive sent
    int64_t autoreport_period_ns = 0;  // M155 S<seconds>: temperature auto-report (0: off)
    int64_t next_autoreport_ns = 0;
    int64_t sd_report_period_ns = 0;  // M27 S<seconds>: print job status auto-report (0: off)
    int64_t next_sd_report_ns = 0;
    std::deque<std::shared_ptr<ReplySlot>> replies;  // Marlin channels: answers not yet sent
    std::optional<UserWait> user_wait;               // an M0 / M1 / M600 in progress
  };
  // A submitted command's answer: its status and the lines it reports before it (CommandDone);
  // Pending: who gets it.
  using DoneFn = std::function<void(const Status&, const std::string& report)>;
  struct Pending {
    uint64_t client_id = 0;
    DoneFn done;
  };
  struct Script;  // a JSON gcode request in progress

  Status open_channels();
  void close_channels();
  void add_client(std::shared_ptr<ClientSession> session, Kind kind);
  void remove_client(uint64_t id);
  Client* find_client(uint64_t id);

  void on_marlin_line(Client& c, std::string_view line, bool too_long);
  void process_marlin_line(Client& c, std::string_view line);
  // Answers queries at once; returns true if `cmd` was one.
  // `client_id`: who asks (the SD-card commands check print ownership; 0: no client).
  bool answer_query(const gcode::Command& cmd, std::string& reply, uint64_t client_id = 0);
  static bool is_query(const gcode::Command& cmd);
  // Marlin's SD-card commands (M20 M21 M23 M24 M25 M26 M27 M32 M524) on the job folder.
  std::string sd_status_line() const;  // M27's line
  bool answer_sd_command(const gcode::Command& cmd, std::string& reply, uint64_t client_id);
  // JobSink
  Offer offer(const gcode::Command& cmd, std::string_view text, std::function<void(const Status&)> done,
              std::string* why) override;
  // machine_status(): declared once above (both interfaces ask the same of the daemon).
  int64_t now_ns() const override { return clock_.now_ns(); }
  void set_input_coming(bool coming) override {
    if (machine_) machine_->set_input_coming(coming);
  }
  void open_jobs();
  // Commands of the daemon's own (heater hook) waiting for room in the machine's queue.
  void flush_internal();
  // Who owns the print, for an error text.
  std::string owner_name() const;
  // A job owns the print only while it sends commands (printing, its pause/resume/cancel moves):
  // once it has parked, been cancelled or finished, the print is free again.
  void release_ownership_of_a_quiet_job() {
    if (owner_ == kJobOwner && (!job_ || !job_->sending())) owner_ = 0;
  }
  // Sends the ready answers at the front of c.replies (queries are answered there).
  void flush_replies(Client& c);
  // Ownership + submit. Returns an error text when refused; parks when the queue is full.
  // `text` is the line as received: recorded with its arrival time when the command is accepted.
  std::string submit(Client& c, const gcode::Command& cmd, std::string_view text,
                     recorder::GcodeSource source, DoneFn done);
  void retry_parked();
  // Works off the lines a client sent while it waited (parked or a user wait), in order.
  void drain_backlog(Client& c);
  void run_script_step(std::shared_ptr<Script> s);
  // daemon_user_wait.cpp: M0 / M1 / M600 from a Marlin client, and the answer that ends them.
  static bool is_user_stop(const gcode::Command& cmd);
  void begin_user_wait(Client& c, const gcode::Command& cmd, std::string_view line);
  void on_user_wait_stopped(uint64_t client_id, const Status& st);
  void on_user_answer();  // M108 / M876 arrived: every wait whose machine has stopped ends
  bool user_waiting() const;  // some client's M0 / M600 has stopped the machine for the user
  void end_user_wait(Client& c, const Status& st);
  // Submits `lines` one after the other for client c; `done` after the last or the first error.
  void run_lines(uint64_t client_id, std::vector<std::string> lines, size_t next,
                 std::function<void(const Status&)> done);
  // The pause's park and return settings (config jobs:), for a job's pause and an M600.
  JobOptions pause_options() const;

  void on_command_done(engine::CommandDone done);  // I/O thread
  void tick();                                     // periodic: subscriptions, ownership, reload
  void reload_config();
  void arm_signals();
  Status start_machine(std::unique_ptr<engine::CommandExecutor> executor, std::string* warnings);
  // The recorder for cfg_ (a failure is a warning: the machine runs unrecorded).
  void open_recorder();
  void close_recorder();
  // The executor with the recorder's taps in it.
  Result<std::unique_ptr<engine::CommandExecutor>> make_recorded_executor();
  void start_print(const std::string& owner_name);
  void end_print();
  std::string firmware_info() const;
  Status open_web();
  void close_web();
  // Shows a line another channel sent in the web console (notify_gcode_response), rate-limited.
  void echo_to_web(const Client& c, std::string_view line, const gcode::Command& cmd);

  config::MachineConfig cfg_;
  DaemonOptions options_;
  std::string calibration_applied_;  // the overlay in cfg_ ("" when none)
  bool open_loop_override_ = false;  // config.reload {open_loop: true}: control.mode open_loop
  bool no_feedforward_override_ = false;  // config.reload {no_feedforward: true}: feedforward none
  boost::asio::io_context io_;
  boost::asio::signal_set signals_;
  boost::asio::steady_timer timer_;
  MonotonicClock clock_;                 // I/O side: timers, ownership, keepalives
  std::unique_ptr<Clock> machine_clock_;  // the machine's time line (virtual or monotonic)
  // Declared before machine_: they outlive the executor that reports to them.
  std::unique_ptr<recorder::Recorder> recorder_;
  std::unique_ptr<recorder::EngineRecording> recording_;
  bool print_open_ = false;
  std::vector<std::string> recorded_logs_;
  std::string last_print_log_;  // the last print's log (its first part), for `status`
  std::unique_ptr<engine::Machine> machine_;
  SystemdNotifier notifier_;

  UnixListener gcode_listener_;
  UnixListener api_listener_;
  PtyChannel pty_;
  std::string socket_path_, api_socket_path_, pty_link_;

  std::map<uint64_t, Client> clients_;  // by internal id
  uint64_t next_client_id_ = 1;
  std::map<uint64_t, Pending> pending_;  // by ticket
  uint64_t next_ticket_ = 1;
  uint64_t owner_ = 0;  // client id owning the print, 0: none
  int64_t owner_last_activity_ns_ = 0;
  int64_t next_heater_log_ns_ = 0;  // the log's temperature line while heaters are on
  uint64_t homings_logged_ = 0;     // the G28s through the endstops already in the log
  bool reload_requested_ = false;   // SIGHUP / RESTART: re-read the config, rebuild when idle
  bool restart_requested_ = false;  // M999: rebuild from the running config when idle
  // M999s waiting for the rebuild they asked for: answered once it ran (or failed).
  std::vector<DoneFn> restart_waiters_;
  uint64_t reloads_ = 0;
  bool shutting_down_ = false;
  RepeatFilter rejected_log_;     // "command rejected" warnings: one line plus a count
  std::string display_message_;  // M117
  int progress_percent_ = -1;    // M73 P
  // The status snapshot, shared by every reply and notification until the next. Renewed when
  // asked for and older than status_period_ms, or stale: a command has completed (or M117/M73, an
  // emergency stop) since, so a status asked after an `ok` shows that command. Builds per second
  // are at most 1000 / status_period_ms plus the machine's command completions.
  struct StatusSnapshot {
    std::shared_ptr<const std::string> text;
    std::string notification;  // the "status" notification around `text`
    int64_t taken_ns = 0;
    uint64_t seq = 0;
    bool stale = true;
  };
  StatusSnapshot snapshot_;

  std::unique_ptr<JobFiles> job_files_;
  std::unique_ptr<PrintJob> job_;
  std::deque<std::pair<gcode::Command, std::string>> internal_backlog_;
  // The web server (web.enabled); its print jobs are job_.
  std::unique_ptr<web::Database> web_db_;
  std::unique_ptr<web::FileStore> web_files_;
  std::unique_ptr<web::MoonrakerApi> web_api_;
  std::unique_ptr<web::HttpServer> web_server_;
  uint64_t web_client_id_ = 0;  // the web's internal client: it owns what the web submits
  // Console echo (Moonraker shows what other channels send): at most kEchoPerSecond lines a
  // second; moves are not echoed (a streamed print would flood the console).
  int64_t echo_window_ns_ = 0;
  int echo_in_window_ = 0;
  uint64_t echo_dropped_ = 0;
  int64_t owner_since_ns_ = 0;  // a streamed print (a client owns the print): since when
};

}  // namespace feedloop::daemon
