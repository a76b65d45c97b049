#include "daemon/daemon.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <spdlog/spdlog.h>

#include <cstdio>  // snprintf
#include <utility>

#include "config/config.hpp"
#include "config/config_source.hpp"
#include "config/enum_names.hpp"
#include "daemon/runtime_dir.hpp"
#include "engine/executor_factory.hpp"
#include "engine/thermal_config.hpp"
#include "gcode/parser.hpp"
#include "recorder/options_from_config.hpp"
#include "recorder/replay.hpp"
#include "web/database.hpp"
#include "web/file_store.hpp"
#include "web/http_server.hpp"
#include "web/moonraker_api.hpp"

namespace feedloop::daemon {

namespace asio = boost::asio;
using nlohmann::json;

namespace {
constexpr auto kTickInterval = std::chrono::milliseconds(5);
constexpr const char* kVersion = "0.1.0";

// Marlin's M105 answer: "ok T:210.0 /210.0 B:60.0 /60.0 @:127 B@:64" (the thermal loop's report;
// a machine without heaters reports ambient zeros as before).
std::string format_temp_reply(const engine::MachineStatus& s) {
  if (s.num_heaters > 0) return std::string("ok ") + s.temp_report;
  char buf[160];
  std::snprintf(buf, sizeof buf, "ok T:%.1f /%.1f B:%.1f /%.1f @:0 B@:0", s.hotend_c,
                s.hotend_target_c, s.bed_c, s.bed_target_c);
  return buf;
}

json heaters_json(const engine::MachineStatus& s) {
  json out = json::array();
  for (int i = 0; i < s.num_heaters; ++i) {
    const engine::HeaterStatus& h = s.heaters[i];
    out.push_back({{"name", h.name},
                   {"temp_c", std::round(h.temp_c * 100.0) / 100.0},
                   {"target_c", h.target_c},
                   {"power", std::round(h.power * 1000.0) / 1000.0},
                   {"faulted", h.faulted},
                   {"autotuning", h.autotuning}});
  }
  return out;
}

json fans_json(const engine::MachineStatus& s) {
  json out = json::array();
  for (int i = 0; i < s.num_fans; ++i)
    out.push_back({{"name", s.fans[i].name}, {"speed", s.fans[i].speed}});
  return out;
}
}  // namespace

// A JSON `gcode` request: its lines run one after the other; the first failure ends it.
struct Daemon::Script {
  uint64_t client_id = 0;
  std::vector<std::string> lines;
  size_t next = 0;
  int64_t line_number = 0;
  json results = json::array();
  std::function<void(json, std::string)> done;
};

Daemon::Daemon(config::MachineConfig cfg, DaemonOptions options)
    : cfg_(std::move(cfg)),
      options_(std::move(options)),
      signals_(io_, SIGINT, SIGTERM, SIGHUP),
      timer_(io_),
      notifier_([this] { return machine_ && machine_->healthy(); }),
      gcode_listener_(io_, "socket"),
      api_listener_(io_, "api"),
      pty_(io_) {}

Daemon::~Daemon() {
  if (machine_) machine_->stop();
  close_channels();
  close_recorder();
}

void Daemon::open_recorder() {
  if (!cfg_.recorder.enabled) return;
  // Joints in the engine's order, up to the last that is an axis of the config.
  std::vector<std::string> names;
  for (const std::string& n : engine::joint_names(cfg_)) names.push_back(n);
  while (!names.empty() && cfg_.axis(names.back()) == nullptr) names.pop_back();
  auto ro = recorder::recorder_options_from_config(cfg_, config::to_yaml(cfg_), names,
                                                   config::path_vars_from_environment());
  if (!ro) {
    spdlog::warn("flight recorder off: {}", ro.error().to_string());
    return;
  }
  ro->clock = machine_clock_.get();
  auto rec = recorder::Recorder::create(std::move(*ro));
  if (!rec) {
    spdlog::warn("flight recorder off: {}", rec.error().to_string());
    return;
  }
  recorder_ = std::move(*rec);
  recording_ = std::make_unique<recorder::EngineRecording>(*recorder_, *machine_clock_);
  // In virtual time nothing waits for the wall clock, so a full ring waits for the recorder
  // thread instead of losing records (a calibration's recording must be whole).
  recorder_->set_wait_for_room(options_.virtual_time);
  recorder_->start_thread();
  spdlog::info("flight recorder: prints are recorded in {}", cfg_.recorder.directory);
}

void Daemon::close_recorder() {
  end_print();
  if (recorder_) recorder_->stop_thread();
  recording_.reset();
  recorder_.reset();
}

Result<std::unique_ptr<engine::CommandExecutor>> Daemon::make_recorded_executor() {
  // A DC-servo machine has no step pipeline to record: its own executor, unrecorded for now.
  if (cfg_.drive == config::Drive::dc_servo) return engine::make_executor(cfg_);
  engine::MotionOptions mo = engine::motion_options(cfg_);
  // In virtual time no time passes while the machine is idle, so no settling to record either
  // (and a tail cut short by the host's next line would make the recording depend on its pace).
  if (options_.virtual_time) mo.settle_tail_s = 0.0;
  // ... and a job that follows an M400 starts from rest, at a virtual instant of its own.
  mo.m400_waits_for_rest = options_.virtual_time;
  auto stack = engine::make_motion_stack(cfg_, mo, recording_.get());
  if (!stack) return stack.error();
  if (recording_) stack->executor->set_telemetry(recording_.get());
  return std::unique_ptr<engine::CommandExecutor>(std::move(stack->executor));
}

void Daemon::start_print(const std::string& owner_name) {
  if (!recorder_ || print_open_) return;
  if (Status s = recorder_->start_print(owner_name); !s) {
    spdlog::warn("flight recorder: cannot start recording the print: {}", s.error().to_string());
    return;
  }
  print_open_ = true;
  recorder_->writer(recorder::Stream::io)
      .event(recorder::EventKind::print_start, machine_clock_->now_ns(), -1, 0.0, owner_name);
}

void Daemon::end_print() {
  if (!recorder_ || !print_open_) return;
  print_open_ = false;
  recorder_->writer(recorder::Stream::io)
      .event(recorder::EventKind::print_end, machine_clock_->now_ns(), -1, 0.0);
  const std::string last = recorder_->stats().current_path;
  if (Status s = recorder_->end_print(); !s)
    spdlog::warn("flight recorder: {}", s.error().to_string());
  const std::string err = recorder_->stats().last_error;
  if (!err.empty()) spdlog::warn("flight recorder: {}", err);
  if (!last.empty()) {
    for (std::string& p : recorder::print_log_parts(last)) recorded_logs_.push_back(std::move(p));
    last_print_log_ = last;
    spdlog::info("print recorded: {}", last);
  }
}

Status Daemon::start() {
  if (options_.virtual_time && !cfg_.uses_simulator())
    return Error{"--virtual-time needs a simulated printer (mcus with transport: mock)"};
  if (options_.virtual_time)
    machine_clock_ = std::make_unique<VirtualClock>();
  else
    machine_clock_ = std::make_unique<MonotonicClock>();
  open_recorder();
  auto executor = make_recorded_executor();
  if (!executor) {
    close_recorder();
    return executor.error();
  }
  std::string warnings;
  if (Status s = start_machine(std::move(*executor), &warnings); !s) return s;
  open_jobs();
  for (size_t b = 0, e; b < warnings.size(); b = e + 1) {
    e = warnings.find('\n', b);
    if (e == std::string::npos) e = warnings.size();
    if (e > b) spdlog::warn("{} (running without real-time guarantees)", warnings.substr(b, e - b));
  }
  if (Status s = open_channels(); !s) {
    machine_->stop();
    close_channels();
    return s;
  }
  arm_signals();
  timer_.expires_after(kTickInterval);
  timer_.async_wait([this](const boost::system::error_code& ec) {
    if (!ec) tick();
  });
  notifier_.ready();
  notifier_.start_watchdog();
  spdlog::info("feedloopd {} ready: '{}' ({}), socket {}, api {}, pty {} -> {}", kVersion,
               cfg_.name, cfg_.uses_simulator() ? "simulated" : "hardware", socket_path_,
               api_socket_path_, pty_link_, pty_.slave_name());
  return Status::Ok();
}

Status Daemon::open_channels() {
  const config::PathVars vars = config::path_vars_from_environment();
  auto sock = config::expand_path(cfg_.sockets.unix_socket, vars);
  auto api = config::expand_path(cfg_.sockets.api_socket, vars);
  auto pty = config::expand_path(cfg_.sockets.pty_link, vars);
  if (!sock) return sock.error();
  if (!api) return api.error();
  if (!pty) return pty.error();
  socket_path_ = *sock;
  api_socket_path_ = *api;
  pty_link_ = *pty;
  std::vector<std::string> warnings;
  if (Status s = check_channel_path("sockets.unix_socket", socket_path_, vars.runtime_dir,
                                    cfg_.sockets.mode, &warnings);
      !s)
    return s;
  if (Status s = check_channel_path("sockets.api_socket", api_socket_path_, vars.runtime_dir,
                                    cfg_.sockets.mode, &warnings);
      !s)
    return s;
  if (Status s = check_channel_path("sockets.pty_link", pty_link_, vars.runtime_dir, 0, &warnings);
      !s)
    return s;
  for (const std::string& w : warnings) spdlog::warn("{}", w);
  if (Status s = gcode_listener_.listen(
          socket_path_, cfg_.sockets.mode,
          [this](auto session) { add_client(std::move(session), Kind::kMarlin); });
      !s)
    return s;
  if (Status s = api_listener_.listen(
          api_socket_path_, cfg_.sockets.mode,
          [this](auto session) { add_client(std::move(session), Kind::kJson); });
      !s)
    return s;
  if (Status s = pty_.open(pty_link_, [this](auto session) { add_client(std::move(session), Kind::kMarlin); }); !s)
    return s;
  return open_web();
}

void Daemon::close_channels() {
  close_web();
  gcode_listener_.close();
  api_listener_.close();
  pty_.close();
}

Status Daemon::start_machine(std::unique_ptr<engine::CommandExecutor> executor,
                             std::string* warnings) {
  // Heaters named on a motion MCU go through that MCU's session in the executor's bridge.
  const engine::SharedHeaterPorts* heater_ports = executor->heater_ports();
  machine_ = std::make_unique<engine::Machine>(engine::machine_options(cfg_), *machine_clock_,
                                               std::move(executor));
  auto thermal = engine::make_thermal_loop(cfg_, heater_ports);
  if (!thermal) return thermal.error();
  machine_->set_thermal(std::move(thermal.value()));
  machine_->set_done_callback([this](engine::CommandDone d) {
    asio::post(io_, [this, d = std::move(d)]() mutable { on_command_done(std::move(d)); });
  });
  return machine_->start(warnings);
}

int Daemon::run() {
  io_.run();
  return 0;
}

void Daemon::request_shutdown(const std::string& why) {
  asio::post(io_, [this, why] {
    if (shutting_down_) return;
    shutting_down_ = true;
    spdlog::info("{}: stopping motion and shutting down", why);
    notifier_.stopping();
    notifier_.stop_watchdog();
    // The two steps that can take time are timed in the log (the process test's 2 s bound).
    const auto t0 = std::chrono::steady_clock::now();
    if (machine_) machine_->stop();  // cancels queued commands; the servo loop ends its cycle
    const auto t1 = std::chrono::steady_clock::now();
    if (const std::string summary = rejected_log_.flush(clock_.now_ns(), true); !summary.empty())
      spdlog::warn("command rejected: {}", summary);
    end_print();
    const auto ms = [](auto d) { return std::chrono::duration<double, std::milli>(d).count(); };
    spdlog::info(
        "shutdown: the machine's threads stopped in {:.0f} ms, the recording closed in {:.0f} ms",
        ms(t1 - t0), ms(std::chrono::steady_clock::now() - t1));
    close_channels();
    std::vector<std::shared_ptr<ClientSession>> sessions;
    for (auto& [id, c] : clients_) sessions.push_back(c.session);
    for (auto& s : sessions) s->close();
    signals_.cancel();
    timer_.cancel();
    spdlog::default_logger()->flush();
    io_.stop();
  });
}

void Daemon::add_client(std::shared_ptr<ClientSession> session, Kind kind) {
  const uint64_t id = next_client_id_++;
  Client& c = clients_[id];
  c.id = id;
  c.session = session;
  c.kind = kind;
  c.last_progress_ns = clock_.now_ns();
  if (kind == Kind::kMarlin) {
    gcode::HostProtocol::Options po;
    po.defer_ok = true;
    po.caller_handles = [](const gcode::Command& cmd) {  // daemon_user_wait.cpp, submit()
      return cmd.is('M', 0) || cmd.is('M', 1) || cmd.is('M', 600) || cmd.is('M', 876);
    };
    c.protocol = std::make_unique<gcode::HostProtocol>(session->name(), po);
    // M108 ends a heater wait or a user's stop (M0 / M600) as it arrives, ahead of the lines
    // waiting before it (Marlin's emergency parser: OctoPrint's "skip heat-up"), and M876 (the
    // answer to a host prompt) a user's stop; the line itself is then answered in order.
    session->set_on_arrival([this](std::string_view line) {
      const bool m108 = gcode::HostProtocol::is_break_and_continue(line);
      if (m108 && machine_) machine_->break_heater_wait();
      if (m108 || gcode::HostProtocol::is_prompt_response(line))
        boost::asio::post(io_, [this] { on_user_answer(); });  // not inside the session's read
    });
  }
  session->set_limits(kind == Kind::kJson ? options_.api_limits : options_.marlin_limits);
  if (kind == Kind::kMarlin) {
    session->set_urgent(
        [](std::string_view line) { return gcode::HostProtocol::is_emergency_stop(line); });
  } else {
    // A stop request never waits behind the client's other requests or its rate limit (a false
    // positive, e.g. the word in a G-code comment, is only handled early).
    session->set_urgent([](std::string_view line) {
      return line.find("\"emergency_stop\"") != std::string_view::npos;
    });
  }
  session->set_handlers(
      [this, id](ClientSession&, std::string_view line, bool too_long) {
        Client* cl = find_client(id);
        if (!cl) return;
        if (cl->kind == Kind::kMarlin) {
          // Every channel handler catches what it throws: the client gets an error, the
          // connection and the print go on.
          try {
            on_marlin_line(*cl, line, too_long);
          } catch (const std::exception& e) {
            spdlog::error("{}: internal error on a line: {}", cl->session->name(), e.what());
            cl->session->send_line(std::string("Error:internal error: ") + e.what());
            cl->session->send_line("ok");
          }
          return;
        }
        if (too_long) {
          cl->session->send_line(to_wire(json_rpc_error(nullptr, -32700, "request line too long")));
          return;
        }
        auto weak = std::weak_ptr<ClientSession>(cl->session);
        handle_json_request_wire(*this, *cl->session, line, cl->subscription,
                                 [weak](std::string wire) {
                                   if (auto s = weak.lock()) s->send_line(wire);
                                 });
      },
      [this, id](ClientSession&) { asio::post(io_, [this, id] { remove_client(id); }); });
  spdlog::debug("client {} connected", session->name());
  session->start();
}

void Daemon::remove_client(uint64_t id) {
  auto it = clients_.find(id);
  if (it == clients_.end()) return;
  spdlog::debug("client {} disconnected", it->second.session->name());
  if (const auto& wait = it->second.user_wait; wait && display_message_ == wait->message) {
    display_message_.clear();  // its M0 / M600 went with it (a parked head stays parked)
    snapshot_.stale = true;
  }
  if (owner_ == id) {
    owner_ = 0;  // commands already queued still run: a vanished client never stalls motion
    spdlog::info("print owner {} disconnected; ownership released", it->second.session->name());
  }
  // A line waiting for room in the machine's queue never reached it: it goes with its client, as
  // the lines behind it do. Its ticket would otherwise stay pending for good, and with it the
  // print's end and every rebuild that waits for nothing pending (M999, SIGHUP).
  if (const auto& parked = it->second.parked) {
    pending_.erase(parked->ticket);
    spdlog::info("{} disconnected with a line waiting for queue room; it is dropped",
                 it->second.session->name());
  }
  clients_.erase(it);
}

Daemon::Client* Daemon::find_client(uint64_t id) {
  auto it = clients_.find(id);
  return it == clients_.end() ? nullptr : &it->second;
}

void Daemon::on_marlin_line(Client& c, std::string_view line, bool too_long) {
  if (gcode::HostProtocol::is_emergency_stop(line)) {  // M112 bypasses every queue
    emergency_stop("M112 from " + c.session->name());
    c.session->send_line(gcode::HostProtocol::kHalted);
    return;
  }
  if (too_long) {
    gcode::Reply reply;
    gcode::SplitLine sl;
    sl.too_long = true;
    sl.length_bytes = ClientSession::kMaxLineBytes + 1;
    c.protocol->on_too_long(sl, reply);
    c.session->send_line(std::string_view(reply.text).substr(0, reply.text.size() - 1));
    return;
  }
  if (c.parked || c.user_wait || !c.backlog.empty()) {
    c.backlog.emplace_back(line);
    return;
  }
  process_marlin_line(c, line);
}

void Daemon::process_marlin_line(Client& c, std::string_view line) {
  gcode::Reply reply;
  gcode::Command cmd;
  const auto action = c.protocol->on_line(line, reply, cmd);
  // Every answer goes out in the order of the lines: behind the answers still pending.
  auto flush = [&] {
    if (!reply.text.empty()) {
      const std::string_view text = std::string_view(reply.text).substr(0, reply.text.size() - 1);
      if (c.replies.empty()) {
        c.session->send_line(text);
      } else {
        auto slot = std::make_shared<ReplySlot>();
        slot->ready = true;
        slot->text = std::string(text);
        c.replies.push_back(std::move(slot));
      }
    }
    reply.clear();
  };
  if (action == gcode::HostProtocol::Action::kEmergencyStop) {
    emergency_stop("M112 from " + c.session->name());
    c.session->send_line(gcode::HostProtocol::kHalted);  // at once, ahead of everything
    return;
  }
  if (action != gcode::HostProtocol::Action::kExecute) {
    flush();
    return;
  }
  flush();  // e.g. "echo:Unknown command"
  echo_to_web(c, line, cmd);
  if (is_user_stop(cmd)) {
    begin_user_wait(c, cmd, line);
    return;
  }
  if (cmd.is('M', 0) || cmd.is('M', 1)) {
    // M0 / M1 with P<ms> or S<s>: Marlin waits that long for a click and goes on; with no panel
    // to click, a dwell (is_user_stop took the forms without).
    const double ms = cmd.has('P') ? cmd.get('P') : 1000.0 * cmd.get('S');
    cmd.clear();
    cmd.letter = 'G';
    cmd.code = 4;
    cmd.set('P', std::max(0.0, ms));
  }
  if (is_query(cmd)) {
    if (cmd.is('M', 155)) {  // Marlin's AUTO_REPORT_TEMPERATURES, per client
      c.autoreport_period_ns = ns_from_seconds(cmd.has('S') ? cmd.get('S') : 0.0);
      c.next_autoreport_ns = clock_.now_ns() + c.autoreport_period_ns;
    }
    if (cmd.is('M', 27) && cmd.has('S') && job_) {  // Marlin's AUTO_REPORT_SD_STATUS, per client
      c.sd_report_period_ns = ns_from_seconds(std::clamp(cmd.get('S'), 0.0, 60.0));
      c.next_sd_report_ns = clock_.now_ns() + c.sd_report_period_ns;
    }
    if (c.replies.empty()) {
      std::string answer;
      answer_query(cmd, answer, c.id);
      c.session->send_line(answer);
    } else {
      auto slot = std::make_shared<ReplySlot>();
      slot->is_query = true;
      slot->query = cmd;
      c.replies.push_back(std::move(slot));
    }
    return;
  }
  auto slot = std::make_shared<ReplySlot>();
  c.replies.push_back(slot);
  const uint64_t cid = c.id;
  const auto source = c.session->name().rfind("pty", 0) == 0 ? recorder::GcodeSource::pty
                                                             : recorder::GcodeSource::socket;
  std::string refused =
      submit(c, cmd, line, source, [this, cid, slot](const Status& st, const std::string& report) {
        if (!report.empty()) slot->text = report + "\n";
        if (!st) slot->text += "Error:" + st.error().to_string() + "\n";
        slot->text += gcode::HostProtocol::kOk;
        slot->ready = true;
        if (Client* cl = find_client(cid)) flush_replies(*cl);
      });
  if (!refused.empty()) {
    slot->text = "Error:" + refused + "\n" + std::string(gcode::HostProtocol::kOk);
    slot->ready = true;
  }
  flush_replies(c);
}

void Daemon::flush_replies(Client& c) {
  while (!c.replies.empty()) {
    ReplySlot& r = *c.replies.front();
    if (r.is_query) {
      answer_query(r.query, r.text, c.id);
    } else if (!r.ready) {
      break;
    }
    c.session->send_line(r.text);
    c.replies.pop_front();
  }
}

namespace {
// Marlin's SD-card commands, answered by the job controller (docs/jobs.md).
bool is_sd_command(const gcode::Command& cmd) {
  if (cmd.letter != 'M') return false;
  switch (cmd.code) {
    case 20: case 21: case 23: case 24: case 25: case 26: case 27: case 32: case 524: return true;
    default: return false;
  }
}
}  // namespace

bool Daemon::is_query(const gcode::Command& cmd) {
  if (cmd.empty()) return true;
  // M900 / SET_PRESSURE_ADVANCE without a value reports it (answered in order, after the
  // commands before it have executed).
  const bool pa_report = cmd.code == 900 && !cmd.has('K') && !cmd.has('S');
  // M220 / M221 without a value report the factor (Marlin's gcode/config/M220.cpp, M221.cpp).
  const bool factor_report =
      (cmd.code == 220 || cmd.code == 221) && !cmd.has('S') && !cmd.has('B') && !cmd.has('R');
  return cmd.letter == 'M' && (cmd.code == 105 || cmd.code == 114 || cmd.code == 115 ||
                               cmd.code == 119 || cmd.code == 117 || cmd.code == 73 ||
                               cmd.code == 155 || pa_report || factor_report || is_sd_command(cmd));
}

bool Daemon::answer_query(const gcode::Command& cmd, std::string& reply, uint64_t client_id) {
  if (cmd.empty()) {
    reply = "ok";
    return true;
  }
  if (cmd.letter != 'M') return false;
  if (is_sd_command(cmd)) return answer_sd_command(cmd, reply, client_id);
  const engine::MachineStatus s = machine_->status();
  char buf[256];
  switch (cmd.code) {
    case 105:
      reply = format_temp_reply(s);
      return true;
    case 155:
      reply = "ok";
      return true;
    case 114: {
      // Marlin's M114: the logical position, then each stepper's step counter
      // (Marlin/src/module/stepper.cpp, Stepper::report_positions; labels from language.h:
      // " Count X:" on Cartesian machines, " Count A:" where the steppers are not the axes).
      const char* labels = cfg_.kinematics == config::Kinematics::delta    ? "A:%lld B:%lld C:%lld"
                           : cfg_.kinematics == config::Kinematics::corexy ? "A:%lld B:%lld Z:%lld"
                                                                           : "X:%lld Y:%lld Z:%lld";
      char count[96];
      std::snprintf(count, sizeof count, labels, static_cast<long long>(s.step_count[0]),
                    static_cast<long long>(s.step_count[1]),
                    static_cast<long long>(s.step_count[2]));
      std::snprintf(buf, sizeof buf, "X:%.2f Y:%.2f Z:%.2f E:%.2f Count %s\nok", s.pos_mm[0],
                    s.pos_mm[1], s.pos_mm[2], s.pos_mm[3], count);
      reply = buf;
      return true;
    }
    case 115:
      reply = firmware_info() + "\nok";
      return true;
    case 900:
      // Marlin's M900 report (gcode/feature/advance/M900.cpp, one extruder): "Advance K=<k>";
      // Klipper's SET_PRESSURE_ADVANCE answers with both values (extruder.py).
      if (cmd.has('K') || cmd.has('S')) return false;
      if (cmd.text == "SET_PRESSURE_ADVANCE")
        std::snprintf(buf, sizeof buf,
                      "// pressure_advance: %.6f\n// pressure_advance_smooth_time: %.6f\nok",
                      s.pressure_advance_s, s.pressure_advance_smooth_time_s);
      else
        std::snprintf(buf, sizeof buf, "echo:Advance K=%.3f\nok", s.pressure_advance_s);
      reply = buf;
      return true;
    case 220:  // Marlin's M220 report: "FR:100%"
    case 221:  // Marlin's M221 report: "echo:E0 Flow: 100%"
      if (cmd.has('S') || cmd.has('B') || cmd.has('R')) return false;
      if (cmd.code == 220)
        std::snprintf(buf, sizeof buf, "FR:%.0f%%\nok", s.speed_factor * 100.0);
      else
        std::snprintf(buf, sizeof buf, "echo:E0 Flow: %.0f%%\nok", s.flow_factor * 100.0);
      reply = buf;
      return true;
    case 119: {
      // Marlin's M119 (gcode/host/M119.cpp, endstops.cpp report_states): "Reporting endstop
      // status", one "x_min: open" / "x_min: TRIGGERED" line per switch, then ok. The states are
      // the MCUs' answers to the ENDSTOP_QUERY the bridge sends every 100 ms (at most that old).
      reply = "Reporting endstop status";
      for (int i = 0; i < 3; ++i) {
        if (s.endstop[i] < 0) continue;
        reply += fmt::format("\n{}_{}: {}", "xyz"[i], s.endstop_at_max[i] ? "max" : "min",
                             s.endstop[i] == 1 ? "TRIGGERED" : "open");
      }
      reply += "\nok";
      return true;
    }
    case 117:
      display_message_ = cmd.text;
      snapshot_.stale = true;
      reply = "ok";
      return true;
    case 73:
      if (cmd.has('P')) progress_percent_ = static_cast<int>(cmd.get('P'));
      snapshot_.stale = true;
      reply = "ok";
      return true;
    default:
      return false;
  }
}

std::string Daemon::firmware_info() const {
  return std::string("FIRMWARE_NAME:feedloop ") + kVersion +
         " SOURCE_CODE_URL:feedloop PROTOCOL_VERSION:1.0 MACHINE_TYPE:" + cfg_.name +
         " EXTRUDER_COUNT:1";
}

std::string Daemon::submit(Client& c, const gcode::Command& cmd, std::string_view text,
                           recorder::GcodeSource source, DoneFn done) {
  const uint64_t cid = c.id;
  if (cmd.is('M', 112)) {  // from whichever channel: an emergency stop, never a queued no-op
    emergency_stop("M112 from " + c.session->name());
    return "Printer halted by M112 (emergency stop); send M999 or restart feedloopd to clear";
  }
  if (cmd.is('M', 108) || cmd.is('M', 876)) {  // their work was done when the line arrived
    done(Status::Ok(), {});
    return {};
  }
  if (cmd.is('M', 999)) {
    // Marlin's M999 (Marlin/src/gcode/control/M999.cpp: back to running after a stop), done as
    // Klipper's FIRMWARE_RESTART: the machine is rebuilt from the config once it is idle, which
    // clears an emergency stop and a thermal fault, turns the heaters off and unhomes the axes.
    // Its ok comes after the rebuild, so the next line runs on the new machine. A machine that
    // is not stopped is left alone (ok at once).
    if (machine_->status().state != engine::MachineState::kEmergencyStopped) {
      done(Status::Ok(), {});
      return {};
    }
    restart_waiters_.push_back(std::move(done));
    if (!restart_requested_)
      spdlog::info("M999 from {}: the machine is rebuilt when idle", c.session->name());
    restart_requested_ = true;
    return {};
  }
  if (machine_->status().state == engine::MachineState::kEmergencyStopped)
    return "Printer halted (emergency stop); send M999 or restart feedloopd to clear";
  // EXCLUDE_OBJECT from any client while another owns the print (Mainsail's "exclude object"
  // during a job, as Klipper takes it from any): it moves nothing, it only tells the planner which
  // of the print's objects to skip, behind the print's commands already queued. It takes no
  // ownership.
  const bool exclusion = cmd.is('M', 486) && cmd.subcode == gcode::kObjectExclude && !cmd.unknown;
  // A job that has just parked owns nothing any more (the tick would release it next): a jog
  // right after the pause is not refused as busy.
  release_ownership_of_a_quiet_job();
  if (owner_ != 0 && owner_ != cid && !exclusion)
    return "busy: the print is owned by " + owner_name();
  if (owner_ != cid && !exclusion) {
    owner_ = cid;
    owner_since_ns_ = clock_.now_ns();
    spdlog::info("{} owns the print", c.session->name());
  }
  if (owner_ == cid) owner_last_activity_ns_ = clock_.now_ns();
  if (recorder_) {
    start_print(c.session->name());
    recorder_->writer(recorder::Stream::io).gcode_line(machine_clock_->now_ns(), source, text);
  }
  const uint64_t ticket = next_ticket_++;
  pending_[ticket] = Pending{cid, std::move(done)};
  // The keepalive's 2 s count from the moment the client starts waiting, not from whenever the
  // last tick happened to see it idle (a command sent right after connecting got "busy" at once).
  if (c.in_flight == 0 && !c.parked) c.last_progress_ns = clock_.now_ns();
  ++c.in_flight;
  c.session->refund();  // paced by the machine's queue, not by the client's rate limit
  if (!machine_->try_submit(ticket, cmd)) {
    c.parked = Parked{ticket, cmd};
    c.session->pause_reading();  // backpressure: the host waits for our ok
  }
  return {};
}

void Daemon::retry_parked() {
  for (auto& [id, c] : clients_) {
    while (c.parked) {
      if (!machine_->try_submit(c.parked->ticket, c.parked->command)) break;
      c.parked.reset();
      drain_backlog(c);
    }
  }
}

void Daemon::drain_backlog(Client& c) {
  while (!c.parked && !c.user_wait && !c.backlog.empty()) {
    std::string line = std::move(c.backlog.front());
    c.backlog.pop_front();
    process_marlin_line(c, line);
  }
  if (!c.parked && !c.user_wait) c.session->resume_reading();
}

void Daemon::on_command_done(engine::CommandDone d) {
  // A status asked after this command's answer shows it (and the snapshot's rate stays bounded
  // by the machine's own pace).
  snapshot_.stale = true;
  auto it = pending_.find(d.ticket);
  if (it == pending_.end()) return;
  Pending p = std::move(it->second);
  pending_.erase(it);
  if (Client* c = find_client(p.client_id)) {
    if (c->in_flight > 0) --c->in_flight;
    c->last_progress_ns = clock_.now_ns();
    if (p.client_id == owner_) owner_last_activity_ns_ = clock_.now_ns();
  }
  if (!d.status) {
    // The same refusal for every later line (a fault): one line, then a count (RepeatFilter).
    std::string summary;
    const bool log = rejected_log_.admit(d.status.error().message, clock_.now_ns(), &summary);
    if (!summary.empty()) spdlog::warn("command rejected: {}", summary);
    if (log) spdlog::warn("command rejected: {}", d.status.error().to_string());
  }
  if (!d.report.empty()) spdlog::info("{}", d.report);
  if (p.done) p.done(d.status, d.report);
}

void Daemon::run_script(ClientSession& client, std::string script,
                        std::function<void(json, std::string)> done) {
  auto s = std::make_shared<Script>();
  for (auto& [id, c] : clients_)
    if (c.session.get() == &client) s->client_id = c.id;
  size_t b = 0;
  while (b <= script.size()) {
    size_t e = script.find('\n', b);
    if (e == std::string::npos) e = script.size();
    s->lines.push_back(script.substr(b, e - b));
    b = e + 1;
  }
  s->done = std::move(done);
  // An M112 anywhere in the script stops the machine now, ahead of the lines before it (as on the
  // Marlin socket: it bypasses every queue); nothing of the script runs.
  for (const std::string& line : s->lines)
    if (gcode::HostProtocol::is_emergency_stop(line)) {
      emergency_stop("M112 from " + client.name());
      json halted = {
          {"line", line}, {"ok", true}, {"reply", std::string(gcode::HostProtocol::kHalted)}};
      s->done({{"results", json::array({std::move(halted)})}}, "");
      return;
    }
  // An M108 in it ends a heater wait now, as on the Marlin socket (the script's lines run in
  // order), and so does it (or an M876) a streaming host's M0 / M600 stop for the user.
  for (const std::string& line : s->lines) {
    const bool m108 = gcode::HostProtocol::is_break_and_continue(line);
    if (machine_ && m108) machine_->break_heater_wait();
    if (m108 || gcode::HostProtocol::is_prompt_response(line))
      asio::post(io_, [this] { on_user_answer(); });
  }
  run_script_step(s);
}

void Daemon::run_script_step(std::shared_ptr<Script> s) {
  Client* c = find_client(s->client_id);
  if (!c) return;  // the client left; queued lines still run
  while (s->next < s->lines.size()) {
    const std::string& text = s->lines[s->next++];
    ++s->line_number;
    auto cmd = gcode::parse_line(
        text, SourceLocation{"api:" + c->session->name(), static_cast<int>(s->line_number), 0});
    if (!cmd) {
      s->results.push_back({{"line", text}, {"ok", false}, {"error", cmd.error().to_string()}});
      s->done({{"results", s->results}}, "");
      return;
    }
    echo_to_web(*c, text, *cmd);
    std::string answer;
    if (answer_query(*cmd, answer, c->id)) {
      s->results.push_back({{"line", text}, {"ok", true}, {"reply", answer}});
      continue;
    }
    if (c->parked) {  // the client already waits for queue room: retry this line later
      --s->next;
      --s->line_number;
      asio::post(io_, [this, s] { run_script_step(s); });
      return;
    }
    std::string refused =
        submit(*c, *cmd, text, recorder::GcodeSource::api,
               [this, s, text](const Status& st, const std::string& report) {
                 s->results.push_back({{"line", text}, {"ok", static_cast<bool>(st)}});
                 if (!report.empty()) s->results.back()["reply"] = report;
                 if (!st) {
                   s->results.back()["error"] = st.error().to_string();
                   s->done({{"results", s->results}}, "");
                   return;
                 }
                 run_script_step(s);
               });
    if (!refused.empty()) {
      s->done({}, refused);
      return;
    }
    return;  // continues in the completion callback
  }
  s->done({{"results", s->results}}, "");
}

void Daemon::emergency_stop(const std::string& reason) {
  spdlog::error("emergency stop: {}", reason);
  machine_->emergency_stop(reason);
  snapshot_.stale = true;
}

json Daemon::info() const {
  const char* kin = cfg_.kinematics == config::Kinematics::delta    ? "delta"
                    : cfg_.kinematics == config::Kinematics::corexy ? "corexy"
                                                                    : "cartesian";
  return {{"name", cfg_.name},
          {"version", kVersion},
          {"api_version", 1},
          {"kinematics", kin},
          {"simulated", cfg_.uses_simulator()},
          {"virtual_time", options_.virtual_time},
          {"servo_rate_hz", cfg_.servo.rate_hz},
          {"config", options_.config_path.empty() ? "(embedded default)" : options_.config_path},
          {"calibration", calibration_applied_},
          {"calibration_path", options_.calibration_path},
          {"open_loop_override", open_loop_override_},
          {"no_feedforward_override", no_feedforward_override_},
          {"control", config::enum_name(config::control_mode_names(), cfg_.control.mode)},
          {"feedforward", config::enum_name(config::feedforward_names(), cfg_.feedforward.type)}};
}

namespace {
// Each MCU link: frames, errors, clock-query round trips (us), the MCU clock's measured rate and
// the transport's queues (back pressure, I/O errors).
json links_json(const engine::LinkTelemetrySet& set) {
  json out = json::array();
  for (int i = 0; i < set.count && i < engine::LinkTelemetrySet::kMaxLinks; ++i) {
    const engine::LinkTelemetry& l = set.links[i];
    out.push_back(
        {{"name", l.name},
         {"state", l.state},
         {"frames_sent", l.frames_sent},
         {"retransmitted", l.retransmitted},
         {"delivered", l.delivered},
         {"duplicates_dropped", l.duplicates_dropped},
         {"out_of_order_dropped", l.out_of_order_dropped},
         {"crc_errors", l.crc_errors},
         {"resets", l.resets},
         {"bytes_written", l.bytes_written},
         {"in_flight", l.in_flight},
         {"rtt_us", {{"last", l.rtt_last_us}, {"min", l.rtt_min_us}, {"mean", l.rtt_mean_us}}},
         {"clock_samples", l.clock_samples},
         {"clock_rate_ppm", l.clock_rate_ppm},
         {"io",
          {{"tx_queue_full", l.tx_queue_full},
           {"tx_blocked", l.tx_blocked},
           {"rx_queue_full", l.rx_queue_full},
           {"errors", l.io_errors},
           {"clock_fit", l.clock_fit_async ? "io_thread" : "inline"}}}});
  }
  return out;
}

// Each joint's device loop (control.loop: device) as its LOOP_REPORTs told it: state, the last
// e = r - y, y and correction u, |e| over the reports while running, the cost of one tick.
json device_loops_json(const engine::DeviceLoopTelemetrySet& set,
                       const std::array<std::string, engine::kJoints>& names) {
  json out = json::object();
  for (size_t j = 0; j < set.size() && j < names.size(); ++j) {
    const engine::DeviceLoopTelemetry& t = set[j];
    if (!t.enabled) continue;
    out[names[j]] = {
        {"state", engine::device_loop_state_name(t.state)},
        {"reports", t.reports},
        {"e_mm", t.e_mm},
        {"y_mm", t.y_mm},
        {"correction_mm", t.correction_mm},
        {"abs_e_mm",
         {{"mean", t.mean_abs_e_mm()}, {"max", t.max_abs_e_mm}, {"samples", t.running_reports}}},
        {"max_abs_correction_mm", t.max_abs_correction_mm},
        {"tick_cost_us",
         {{"last", t.tick_cost_us}, {"mean", t.mean_tick_cost_us()}, {"max", t.max_tick_cost_us}}},
        {"ticks", t.ticks},
        {"deadline_misses", t.deadline_misses},
        {"encoder_rejects", t.encoder_rejects},
        {"slips", t.slips}};
  }
  return out;
}
}  // namespace

// Homing through the endstops (docs/homing.md): each axis's homed position from its switch (null:
// not homed that way), the G28s done so, whether one runs, and the switches as last queried (M119).
static json homing_json(const engine::MachineStatus& s) {
  json pos = json::object(), sw = json::object();
  for (int i = 0; i < 3; ++i) {
    const std::string axis(1, "xyz"[i]);
    pos[axis] =
        std::isfinite(s.homed_position_mm[i]) ? json(s.homed_position_mm[i]) : json(nullptr);
    if (s.endstop[i] >= 0)
      sw[axis + (s.endstop_at_max[i] ? "_max" : "_min")] = s.endstop[i] == 1 ? "TRIGGERED" : "open";
  }
  return {
      {"homed_position_mm", pos}, {"homings", s.homings}, {"running", s.homing}, {"endstops", sw}};
}

json Daemon::status() const {
  const engine::MachineStatus s = machine_->status();
  const engine::ServoStatus v = machine_->servo_status();
  const Client* o = nullptr;
  if (auto it = clients_.find(owner_); it != clients_.end()) o = &it->second;
  return {{"state", engine::to_string(s.state)},
          {"position_mm",
           {{"x", s.pos_mm[0]}, {"y", s.pos_mm[1]}, {"z", s.pos_mm[2]}, {"e", s.pos_mm[3]}}},
          {"homed_axes", std::string(s.homed_axes)},
          {"homing", homing_json(s)},
          {"temperatures_c",
           {{"hotend", s.hotend_c},
            {"hotend_target", s.hotend_target_c},
            {"bed", s.bed_c},
            {"bed_target", s.bed_target_c}}},
          {"heaters", heaters_json(s)},
          {"fans", fans_json(s)},
          {"queue", {{"depth", s.queue_depth}, {"capacity", s.queue_capacity}}},
          {"commands",
           {{"executed", s.commands_executed},
            {"rejected", s.commands_rejected},
            {"flushed", s.commands_flushed}}},
          {"servo",
           {{"cycles", v.cycles},
            {"deadline_misses", v.deadline_misses},
            {"latency_us",
             {{"p50", v.latency.percentile_ns(0.50) / 1000.0},
              {"p99", v.latency.percentile_ns(0.99) / 1000.0},
              {"max", v.latency.max_ns / 1000.0}}}}},
          {"motion",
           {{"moving", s.moving},
            {"print_time_s", s.print_time_s},
            {"planned_until_s", s.planned_until_s},
            {"pressure_advance",
             {{"advance_s", s.pressure_advance_s},
              {"smooth_time_s", s.pressure_advance_smooth_time_s}}},
            {"moves_planned", s.moves_planned},
            {"motion_starts", s.motion_starts},
            {"lost_step_events", s.lost_step_events},
            {"tracking_error_mm",
             {{"mean", s.tracking_error_mean_mm},
              {"max", s.tracking_error_max_mm},
              {"samples", s.tracking_error_samples}}},
            {"late_cycles", s.late_cycles},
            {"segments_queued", s.segments_queued},
            {"device_loops", device_loops_json(s.device_loops, engine::joint_names(cfg_))}}},
          {"links", links_json(s.links)},
          {"clients", clients_.size()},
          {"owner", owner_ == kJobOwner ? json(owner_name())
                    : o                 ? json(o->session->name())
                                        : json(nullptr)},
          {"job", job_status_json()},
          {"progress_percent", progress_percent_},
          {"message", display_message_},
          {"config_reloads", reloads_},
          {"recorder", {{"recording", print_open_}, {"last_print", last_print_log_}}},
          {"last_error", s.last_error}};
}

std::shared_ptr<const std::string> Daemon::status_text() {
  const int64_t now = clock_.now_ns();
  if (snapshot_.text && !snapshot_.stale &&
      now - snapshot_.taken_ns < static_cast<int64_t>(options_.status_period_ms) * 1'000'000)
    return snapshot_.text;
  json s = status();
  s["snapshot"] = {{"seq", ++snapshot_.seq}, {"period_ms", options_.status_period_ms}};
  snapshot_.text = std::make_shared<const std::string>(to_wire(s));
  // {"jsonrpc":"2.0","method":"status","params":...}: what to_wire(json_rpc_notification()) makes.
  snapshot_.notification.clear();
  snapshot_.notification.reserve(snapshot_.text->size() + 48);
  snapshot_.notification += R"({"jsonrpc":"2.0","method":"status","params":)";
  snapshot_.notification += *snapshot_.text;
  snapshot_.notification += '}';
  snapshot_.taken_ns = now;
  snapshot_.stale = false;
  return snapshot_.text;
}

void Daemon::tick() {
  if (shutting_down_) return;
  retry_parked();
  flush_internal();
  if (job_) job_->pump();
  const int64_t now = clock_.now_ns();
  // Ownership ends after the owner has been idle long enough; a job owns the print while it
  // sends commands (printing and its pause/resume/cancel moves; not while paused).
  if (owner_ == kJobOwner) {
    release_ownership_of_a_quiet_job();
  } else if (owner_ != 0 && machine_->idle()) {
    const Client* o = find_client(owner_);
    if (!o || (o->in_flight == 0 && !o->parked && !o->user_wait &&
               now - owner_last_activity_ns_ > ns_from_seconds(options_.ownership_idle_s))) {
      owner_ = 0;
    }
  }
  // Marlin's host keepalive: a command that blocks (the machine is catching up, a heater wait)
  // gets "echo:busy: processing" every 2 s so hosts do not time out.
  for (auto& [id, c] : clients_) {
    if (c.kind != Kind::kMarlin || (c.in_flight == 0 && !c.parked && !c.user_wait)) {
      c.last_progress_ns = now;
      continue;
    }
    if (now - c.last_progress_ns > 2 * kNsPerS) {
      // Marlin's PAUSED_FOR_USER keepalive while an M0 / M600 waits for its answer.
      c.session->send_line(c.user_wait && c.user_wait->waiting ? "echo:busy: paused for user"
                                                               : "echo:busy: processing");
      c.last_progress_ns = now;
    }
  }
  // M155 auto-reports (Marlin sends " T:.. /.. B:.. /.. @:.. B@:.." without an ok), and a log line
  // every 5 s while a heater is on, so the log shows the temperatures settling.
  {
    bool due = now >= next_heater_log_ns_;
    for (auto& [id, c] : clients_)
      due = due ||
            (c.kind == Kind::kMarlin && c.autoreport_period_ns > 0 && now >= c.next_autoreport_ns);
    if (due) {  // a status copy only when something needs it
      const engine::MachineStatus ms = machine_->status();
      for (auto& [id, c] : clients_) {
        if (c.kind != Kind::kMarlin || c.autoreport_period_ns <= 0 || now < c.next_autoreport_ns)
          continue;
        c.session->send_line(" " + format_temp_reply(ms).substr(3));
        c.next_autoreport_ns = now + c.autoreport_period_ns;
      }
      if (ms.homings != homings_logged_) {  // G28 through the endstops: where each axis homed
        homings_logged_ = ms.homings;
        std::string where;
        for (int i = 0; i < 3; ++i)
          if (std::isfinite(ms.homed_position_mm[i]))
            where += fmt::format("{}{} {:.4f} mm", where.empty() ? "" : ", ", "xyz"[i],
                                 ms.homed_position_mm[i]);
        spdlog::info("homed through the endstops ({} G28 so far): {}", ms.homings, where);
      }
      if (now >= next_heater_log_ns_) {
        bool heating = false;
        for (int i = 0; i < ms.num_heaters; ++i) heating = heating || ms.heaters[i].target_c > 0;
        if (heating) spdlog::info("heaters: {}", ms.temp_report);
        next_heater_log_ns_ = now + (heating ? 5 : 1) * kNsPerS;
      }
    }
  }
  // M27 S auto-reports of the print job (Marlin's CardReader::report_status, without an ok).
  for (auto& [id, c] : clients_) {
    if (c.kind != Kind::kMarlin || c.sd_report_period_ns <= 0 || now < c.next_sd_report_ns || !job_)
      continue;
    c.session->send_line(sd_status_line());
    c.next_sd_report_ns = now + c.sd_report_period_ns;
  }
  // Lines waiting for their turn or for the rate limit; flooding clients are dropped here.
  {
    std::vector<std::shared_ptr<ClientSession>> sessions;
    sessions.reserve(clients_.size());
    for (auto& [id, c] : clients_)
      if (c.session->queued_lines() > 0) sessions.push_back(c.session);
    for (auto& s : sessions) s->service();
  }
  // Status subscriptions, from the snapshot (notifications are droppable for slow readers).
  for (auto& [id, c] : clients_) {
    if (c.kind != Kind::kJson || !c.subscription.status || now < c.next_status_ns) continue;
    status_text();
    c.session->send_line(snapshot_.notification, /*droppable=*/true);
    c.next_status_ns = now + static_cast<int64_t>(c.subscription.interval_ms) * 1'000'000;
  }
  if (const std::string summary = rejected_log_.flush(now); !summary.empty())
    spdlog::warn("command rejected: {}", summary);
  // The print ends when nobody owns the machine any more and it has stopped.
  if (print_open_ && owner_ == 0 && machine_->idle() && pending_.empty()) end_print();
  // Not under a paused job or a host's M0 / M600 either: the rebuilt machine would forget where
  // the head was parked from.
  const bool user_waits = std::any_of(clients_.begin(), clients_.end(), [](const auto& kv) {
    return kv.second.user_wait.has_value();
  });
  if ((reload_requested_ || restart_requested_) && machine_->idle() && pending_.empty() &&
      !(job_ && job_->active()) && !user_waits)
    reload_config();
  timer_.expires_after(kTickInterval);
  timer_.async_wait([this](const boost::system::error_code& ec) {
    if (!ec) tick();
  });
}

void Daemon::arm_signals() {
  signals_.async_wait([this](const boost::system::error_code& ec, int sig) {
    if (ec) return;
    if (sig == SIGHUP) {
      reload_requested_ = true;
      spdlog::info("SIGHUP: the config will be re-read when the machine is idle");
      arm_signals();
      return;
    }
    request_shutdown(sig == SIGINT ? "SIGINT" : "SIGTERM");
  });
}

// SIGHUP: re-read the config file and rebuild the machine with it, only when idle. A config
// with errors is reported and the running one is kept. Socket paths take effect on restart.
void Daemon::reload_config() {
  // SIGHUP and the web's RESTART re-read the file; M999 alone rebuilds from the running config.
  const bool reread = reload_requested_;
  reload_requested_ = false;
  restart_requested_ = false;
  // The M999s waiting for this rebuild: ok once it ran, else the reason.
  std::vector<DoneFn> waiters;
  waiters.swap(restart_waiters_);
  auto answer = [&waiters](const Status& st) {
    for (auto& w : waiters)
      if (w) w(st, {});
  };
  notifier_.reloading();
  Result<config::MachineConfig> next = cfg_;
  if (reread) {
    auto loaded = config::load_machine_config(
        {options_.config_path, options_.calibration_path, options_.calibration_required});
    if (!loaded)
      next = loaded.error();
    else {
      for (const std::string& c : loaded.value().changes)
        spdlog::info("calibration {}: {}", loaded.value().calibration, c);
      calibration_applied_ = loaded.value().calibration;
      next = std::move(loaded.value().config);
      if (open_loop_override_) {
        next.value().control.mode = config::ControlMode::open_loop;
        spdlog::info("config reload: open loop until the next config.reload (calibration)");
      }
      if (no_feedforward_override_) {  // with open loop: the steps are the plan (F = 1)
        next.value().feedforward.type = config::FeedforwardType::none;
        spdlog::info("config reload: no feedforward until the next config.reload (calibration)");
      }
    }
  }
  if (!next) {
    spdlog::error("config reload failed, keeping the running config:\n{}",
                  next.error().to_string());
    notifier_.ready();
    answer(Error{"M999: the config does not load, the machine was not rebuilt: " +
                 next.error().to_string()});
    return;
  }
  auto executor = engine::make_executor(*next);
  if (!executor) {
    spdlog::error("config reload failed, keeping the running config: {}",
                  executor.error().to_string());
    notifier_.ready();
    answer(Error{"M999: the machine was not rebuilt: " + executor.error().to_string()});
    return;
  }
  machine_->stop();
  cfg_ = std::move(*next);
  // The recorder follows the new config (joints, steps/mm, directory): a new one, and the
  // executor again, with its taps.
  close_recorder();
  open_recorder();
  executor = make_recorded_executor();
  if (!executor) {
    spdlog::critical("machine failed to restart after reload: {}", executor.error().to_string());
    answer(Error{"machine failed to restart: " + executor.error().to_string()});
    request_shutdown("reload failure");
    return;
  }
  std::string warnings;
  if (Status st = start_machine(std::move(*executor), &warnings); !st) {
    spdlog::critical("machine failed to restart after reload: {}", st.error().to_string());
    answer(Error{"machine failed to restart: " + st.error().to_string()});
    request_shutdown("reload failure");
    return;
  }
  open_jobs();
  ++reloads_;
  if (reread)
    spdlog::info("config reloaded: '{}'", cfg_.name);
  else
    spdlog::info("machine rebuilt (M999): '{}'", cfg_.name);
  notifier_.ready();
  answer(Status::Ok());
}

}  // namespace feedloop::daemon
