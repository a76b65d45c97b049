// feedloopd's print jobs: the job folder, the job controller's link to the machine (JobSink), the
// JSON API's files.* / job.* methods, Marlin's SD-card commands and the heater hook (docs/jobs.md).
#include <spdlog/spdlog.h>

#include <cmath>

#include "config/config.hpp"
#include "daemon/daemon.hpp"
#include "gcode/parser.hpp"

namespace feedloop::daemon {

using nlohmann::json;

namespace {

// RFC 4648 base64 (padding optional, no whitespace); nullopt and the offending offset on error.
std::optional<std::string> decode_base64(std::string_view in, size_t* bad_at) {
  auto value = [](char c) -> int {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    return -1;
  };
  std::string out;
  out.reserve(in.size() / 4 * 3 + 3);
  uint32_t acc = 0;
  int bits = 0;
  size_t end = in.size();
  while (end > 0 && in[end - 1] == '=') --end;
  if (in.size() - end > 2) {
    *bad_at = end;
    return std::nullopt;
  }
  for (size_t i = 0; i < end; ++i) {
    const int v = value(in[i]);
    if (v < 0) {
      *bad_at = i;
      return std::nullopt;
    }
    acc = (acc << 6) | static_cast<uint32_t>(v);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(static_cast<char>((acc >> bits) & 0xFF));
    }
  }
  return out;
}

json position_json(const JobPosition& p) {
  if (!p.valid) return nullptr;
  return {{"pos_mm", {p.pos_mm[0], p.pos_mm[1], p.pos_mm[2], p.pos_mm[3]}},
          {"step_count", {p.step_count[0], p.step_count[1], p.step_count[2], p.step_count[3]}},
          {"encoder_mm", {p.encoder_mm[0], p.encoder_mm[1], p.encoder_mm[2], p.encoder_mm[3]}}};
}

json file_json(const JobFileInfo& f) {
  return {{"filename", f.name}, {"size", f.size_bytes}, {"modified", f.modified_unix_s}};
}

std::string trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return std::string(s);
}

}  // namespace

void Daemon::open_jobs() {
  if (job_ && job_->active()) return;  // never while a job runs (reload waits for that)
  job_.reset();
  job_files_.reset();
  auto dir = config::expand_path(cfg_.jobs.directory, config::path_vars_from_environment());
  if (!dir) {
    spdlog::warn("print jobs off: {}", dir.error().to_string());
    return;
  }
  auto files = std::make_unique<JobFiles>(
      *dir, static_cast<uint64_t>(cfg_.jobs.max_file_size_mb * 1024.0 * 1024.0));
  if (Status s = files->open(); !s) {
    spdlog::warn("print jobs off: {}", s.error().to_string());
    return;
  }
  const JobOptions o = pause_options();
  job_files_ = std::move(files);
  job_ = std::make_unique<PrintJob>(*job_files_, o, static_cast<JobSink&>(*this));
  spdlog::info("print jobs: files in {}", job_files_->directory());
}

JobOptions Daemon::pause_options() const {
  JobOptions o;
  o.pause_retract_mm = cfg_.jobs.pause_retract_mm;
  o.retract_speed_mm_s = cfg_.jobs.retract_speed_mm_s;
  o.prime_extra_mm = cfg_.jobs.prime_extra_mm;
  o.lift_mm = cfg_.jobs.lift_mm;
  o.z_speed_mm_s = cfg_.jobs.z_speed_mm_s;
  o.travel_speed_mm_s = cfg_.jobs.travel_speed_mm_s;
  o.settle_ms = static_cast<int>(std::lround(cfg_.jobs.settle_ms));
  o.park_x_mm = cfg_.jobs.park_x_mm;
  o.park_y_mm = cfg_.jobs.park_y_mm;
  const config::AxisConfig* x = cfg_.axis("x");
  const config::AxisConfig* y = cfg_.axis("y");
  const config::AxisConfig* z = cfg_.axis("z");
  // Marlin's NOZZLE_PARK_POINT default: { X_MIN_POS + 10, Y_MAX_POS - 10 } (Configuration.h).
  if (cfg_.kinematics != config::Kinematics::delta && x && y) {
    if (!o.park_x_mm) o.park_x_mm = std::min(x->min_mm + 10.0, x->max_mm);
    if (!o.park_y_mm) o.park_y_mm = std::max(y->max_mm - 10.0, y->min_mm);
    o.x_min_mm = x->min_mm;
    o.x_max_mm = x->max_mm;
    o.y_min_mm = y->min_mm;
    o.y_max_mm = y->max_mm;
  }
  if (z && std::isfinite(z->max_mm)) o.z_max_mm = z->max_mm;
  return o;
}

std::string Daemon::owner_name() const {
  if (owner_ == kJobOwner) return "the print job '" + (job_ ? job_->file() : std::string()) + "'";
  if (const auto it = clients_.find(owner_); it != clients_.end())
    return it->second.session->name();
  return "another client";
}

JobSink::Offer Daemon::offer(const gcode::Command& cmd, std::string_view text,
                             std::function<void(const Status&)> done, std::string* why) {
  if (cmd.is('M', 112)) {  // an M112 in the job's file stops the machine when the job reaches it
    emergency_stop("M112 in the print job '" + (job_ ? job_->file() : std::string()) + "'");
    *why = "M112: emergency stop";
    return Offer::kRefused;
  }
  if (machine_->status().state == engine::MachineState::kEmergencyStopped) {
    *why = "Printer halted (emergency stop); send M999 or restart feedloopd to clear";
    return Offer::kRefused;
  }
  if (!internal_backlog_.empty()) return Offer::kFull;  // the heater hook's commands go first
  if (owner_ != 0 && owner_ != kJobOwner) {
    *why = "busy: the print is owned by " + owner_name();
    return Offer::kRefused;
  }
  const uint64_t ticket = next_ticket_;
  if (!machine_->try_submit(ticket, cmd)) return Offer::kFull;  // paced by the machine's queue
  ++next_ticket_;
  if (owner_ != kJobOwner)
    spdlog::info("print job '{}' owns the print", job_ ? job_->file() : std::string());
  owner_ = kJobOwner;
  owner_last_activity_ns_ = clock_.now_ns();
  // A job's command reports (M303's values) reach the log (on_command_done), not the job.
  pending_[ticket] =
      Pending{kJobOwner, [done = std::move(done)](const Status& st, const std::string&) {
                if (done) done(st);
              }};
  if (recorder_) {
    start_print("job " + (job_ ? job_->file() : std::string()));
    recorder_->writer(recorder::Stream::io)
        .gcode_line(machine_clock_->now_ns(), recorder::GcodeSource::file, text);
  }
  return Offer::kAccepted;
}

void Daemon::set_heater_target(Heater heater, double target_c) {
  char line[48];
  std::snprintf(line, sizeof line, "%s S%.1f", heater == Heater::kHotend ? "M104" : "M140",
                target_c);
  auto cmd = gcode::parse_line(line, SourceLocation{"heater hook", 1, 0});
  if (!cmd) {
    spdlog::error("heater hook: {}", cmd.error().to_string());
    return;
  }
  internal_backlog_.emplace_back(std::move(*cmd), line);
  flush_internal();
}

void Daemon::all_heaters_off() {
  set_heater_target(Heater::kHotend, 0.0);
  set_heater_target(Heater::kBed, 0.0);
}

void Daemon::cancel_motion() {
  spdlog::info("cancel: the machine's queue dropped, the motion stopping, every heater off");
  machine_->flush(/*heaters_off=*/true);
}

void Daemon::flush_internal() {
  while (!internal_backlog_.empty()) {
    const uint64_t ticket = next_ticket_;
    if (!machine_->try_submit(ticket, internal_backlog_.front().first)) return;
    ++next_ticket_;
    pending_[ticket] = Pending{0, nullptr};
    if (recorder_ && print_open_)
      recorder_->writer(recorder::Stream::io)
          .gcode_line(machine_clock_->now_ns(), recorder::GcodeSource::other,
                      internal_backlog_.front().second);
    internal_backlog_.pop_front();
  }
}

Result<std::vector<JobFileInfo>> Daemon::job_files_list() const {
  if (!job_files_) return Error{"print jobs are off (see the daemon's log: jobs.directory)"};
  return job_files_->list();
}

Result<JobFileInfo> Daemon::job_file_upload(const std::string& name, std::string_view content) {
  if (!job_files_) return Error{"print jobs are off (see the daemon's log: jobs.directory)"};
  if (job_ && job_->active() && job_->file() == name)
    return Error{"'" + name + "' is being printed: cancel the job before replacing it"};
  return job_files_->write(name, content);
}

Status Daemon::job_file_delete(const std::string& name) {
  if (!job_files_) return Error{"print jobs are off (see the daemon's log: jobs.directory)"};
  if (job_ && job_->active() && job_->file() == name)
    return Error{"'" + name + "' is being printed: cancel the job before deleting it"};
  return job_files_->remove(name);
}

Status Daemon::job_start(const std::string& name, uint64_t requester) {
  if (!job_) return Error{"print jobs are off (see the daemon's log: jobs.directory)"};
  if (owner_ != 0 && owner_ != requester && owner_ != kJobOwner)
    return Error{"busy: the print is owned by " + owner_name()};
  // The asking client owns the print (it moved the machine a moment ago): the job takes the
  // print over; its commands queue behind the client's in the one machine queue. Without this,
  // the job's first offer() was refused as busy (owned by the client that started it).
  if (owner_ == requester && requester != 0) owner_ = 0;
  return job_->start(name);
}

Status Daemon::job_pause() {
  if (!job_) return Error{"print jobs are off"};
  return job_->pause();
}

Status Daemon::job_resume(uint64_t requester) {
  if (!job_) return Error{"print jobs are off"};
  if (job_->state() == JobState::kPaused && owner_ != 0 && owner_ != requester &&
      owner_ != kJobOwner)
    return Error{"busy: the print is owned by " + owner_name() + " (moves made while paused)"};
  if (job_->state() == JobState::kPaused && owner_ == requester && requester != 0)
    owner_ = 0;  // as in job_start: the job takes the print back from the client that asks
  return job_->resume();
}

Status Daemon::job_cancel() {
  if (!job_) return Error{"print jobs are off"};
  return job_->cancel();
}

JobStatus Daemon::print_job_status() const {
  return job_ ? job_->status() : JobStatus{};
}

json Daemon::job_status_json() const {
  if (!job_) return {{"state", "off"}};
  const JobStatus j = job_->status();
  return {{"state", to_string(j.state)},
          {"filename", j.file.empty() ? json(nullptr) : json(j.file)},
          {"size_bytes", j.size_bytes},
          {"position_bytes", j.bytes_submitted},
          {"lines_read", j.lines_read},
          {"lines_submitted", j.lines_submitted},
          {"progress", {{"bytes", j.progress_bytes}, {"time", j.progress_time}}},
          {"print_time_s", j.print_time_s},
          {"estimated_total_s", j.estimated_total_s},
          {"estimated_remaining_s", j.estimated_remaining_s},
          {"elapsed_s", j.elapsed_s},
          {"paused_s", j.paused_s},
          {"pauses", j.pauses},
          {"filament_used_mm", j.filament_used_mm},
          {"message", j.message},
          {"pause_position", position_json(j.pause_position)},
          {"resume_position", position_json(j.resume_position)}};
}

std::optional<MethodResult> Daemon::call_method(ClientSession& client, const std::string& method,
                                                const json& params) {
  if (method.rfind("files.", 0) != 0 && method.rfind("job.", 0) != 0 && method != "config.reload")
    return std::nullopt;
  uint64_t requester = 0;
  for (const auto& [id, c] : clients_)
    if (c.session.get() == &client) requester = id;
  auto invalid = [](std::string why) { return MethodResult{nullptr, -32602, std::move(why)}; };
  auto machine_error = [](const Error& e) { return MethodResult{nullptr, -32000, e.to_string()}; };
  if (method == "config.reload") {  // as SIGHUP: the config and its calibration, once idle
    // open_loop: true runs the rebuilt machine open loop whatever the config says (feedloop
    // calibrate's excitation: the steps are then the whole motor command); no_feedforward: true
    // without its feedforward too (the open-loop check: the steps are the plan). false, or a
    // reload without them, ends them.
    for (const char* key : {"open_loop", "no_feedforward"})
      if (params.contains(key) && !params[key].is_boolean())
        return invalid(std::string("'") + key + "' must be true or false");
    open_loop_override_ = params.value("open_loop", false);
    no_feedforward_override_ = params.value("no_feedforward", false);
    restart();
    return MethodResult{{{"reload", "requested"},
                         {"config_reloads", reloads_},
                         {"open_loop", open_loop_override_},
                         {"no_feedforward", no_feedforward_override_}}};
  }
  auto filename = [&params](std::string* out) -> bool {
    if (!params.contains("filename") || !params["filename"].is_string()) return false;
    *out = params["filename"].get<std::string>();
    return true;
  };
  if (method == "files.list") {
    auto files = job_files_list();
    if (!files) return machine_error(files.error());
    json list = json::array();
    for (const JobFileInfo& f : *files) list.push_back(file_json(f));
    return MethodResult{
        {{"files", list}, {"directory", job_files_ ? job_files_->directory() : ""}}};
  }
  if (method == "files.upload") {
    std::string name;
    if (!filename(&name)) return invalid("'filename' (a string) is required");
    std::string content;
    if (params.contains("content") && params["content"].is_string()) {
      content = params["content"].get<std::string>();
    } else if (params.contains("content_base64") && params["content_base64"].is_string()) {
      size_t bad = 0;
      auto decoded = decode_base64(params["content_base64"].get_ref<const std::string&>(), &bad);
      if (!decoded)
        return invalid("'content_base64' is not base64 (at character " + std::to_string(bad + 1) +
                       ")");
      content = std::move(*decoded);
    } else {
      return invalid("'content' (text) or 'content_base64' is required");
    }
    auto info = job_file_upload(name, content);
    if (!info) return machine_error(info.error());
    return MethodResult{file_json(*info)};
  }
  if (method == "files.delete") {
    std::string name;
    if (!filename(&name)) return invalid("'filename' (a string) is required");
    if (Status s = job_file_delete(name); !s) return machine_error(s.error());
    return MethodResult{{{"deleted", name}}};
  }
  Status st = Status::Ok();
  if (method == "job.start") {
    std::string name;
    if (!filename(&name)) return invalid("'filename' (a string) is required");
    st = job_start(name, requester);
  } else if (method == "job.pause") {
    st = job_pause();
  } else if (method == "job.resume") {
    st = job_resume(requester);
  } else if (method == "job.cancel") {
    st = job_cancel();
  } else if (method != "job.status") {
    return std::nullopt;
  }
  if (!st) return machine_error(st.error());
  snapshot_.stale = true;
  return MethodResult{job_status_json()};
}

// Marlin's CardReader::report_status: the job's progress in bytes, or that none prints.
std::string Daemon::sd_status_line() const {
  if (!job_ || !job_->active()) return "Not SD printing";
  const JobStatus j = job_->status();
  return "SD printing byte " + std::to_string(j.bytes_submitted) + "/" +
         std::to_string(j.size_bytes);
}

// Marlin's SD-card commands on the job folder (marlinfw.org/docs/gcode/M020.html ... M032, M524;
// the texts follow Marlin's CardReader messages).
bool Daemon::answer_sd_command(const gcode::Command& cmd, std::string& reply, uint64_t client_id) {
  if (!job_) {
    reply =
        cmd.code == 21 ? "echo:SD init fail\nok" : "Error:print jobs are off (jobs.directory)\nok";
    return true;
  }
  auto fail = [&reply](const std::string& why) { reply = "Error:" + why + "\nok"; };
  auto opened = [](const JobFileInfo& f) {
    return "echo:Now fresh file: " + f.name + "\nFile opened: " + f.name +
           " Size: " + std::to_string(f.size_bytes) + "\nFile selected\n";
  };
  snapshot_.stale = true;
  switch (cmd.code) {
    case 20: {  // M20: list
      auto files = job_files_->list();
      if (!files) {
        fail(files.error().to_string());
        return true;
      }
      reply = "Begin file list\n";
      for (const JobFileInfo& f : *files)
        reply += f.name + " " + std::to_string(f.size_bytes) + "\n";
      reply += "End file list\nok";
      return true;
    }
    case 21:  // M21: init the card (the folder is always there)
      reply = "echo:SD card ok\nok";
      return true;
    case 23: {  // M23: select
      const std::string name = trim(cmd.text);
      auto info = job_->select(name);
      if (!info) {
        reply = "echo:open failed, File: " + name + ". (" + info.error().message + ")\nok";
        return true;
      }
      reply = opened(*info) + "ok";
      return true;
    }
    case 24: {  // M24: start or resume
      Status s =
          job_->state() == JobState::kPaused ? job_resume(client_id) : job_start("", client_id);
      if (!s)
        fail(s.error().message);
      else
        reply = "ok";
      return true;
    }
    case 25:  // M25: pause
      if (Status s = job_pause(); !s)
        fail(s.error().message);
      else
        reply = "ok";
      return true;
    case 26:  // M26 S<byte>: position of the selected file
      if (!cmd.has('S')) {
        fail("M26 needs S<byte position>");
        return true;
      }
      if (Status s = job_->set_start_byte(static_cast<uint64_t>(cmd.get('S'))); !s)
        fail(s.error().message);
      else
        reply = "ok";
      return true;
    case 27: {  // M27: progress; M27 C: the current file; M27 S<s>: auto-report every s (0: off)
      const JobStatus j = job_->status();
      if (cmd.has('S')) {
        reply = "ok";  // the period is the client's (Daemon::on_line)
      } else if (cmd.has('C')) {
        reply = "Current file: " + (j.file.empty() ? std::string("(no file)") : j.file) + "\nok";
      } else {
        reply = sd_status_line() + "\nok";
      }
      return true;
    }
    case 32: {  // M32 [S<byte>] [P] !name# : select and start
      std::string text = trim(cmd.text);
      std::string name = text;
      uint64_t start_byte = 0;
      if (const size_t bang = text.find('!'); bang != std::string::npos) {
        const size_t hash = text.find('#', bang + 1);
        name =
            text.substr(bang + 1, hash == std::string::npos ? std::string::npos : hash - bang - 1);
        const std::string head = text.substr(0, bang);
        if (const size_t sp = head.find('S'); sp != std::string::npos)
          start_byte = std::strtoull(head.c_str() + sp + 1, nullptr, 10);
      }
      name = trim(name);
      if (job_->active()) {
        fail("a print job is active ('" + job_->file() + "'): cancel it first");
        return true;
      }
      if (owner_ != 0 && owner_ != client_id && owner_ != kJobOwner) {
        fail("busy: the print is owned by " + owner_name());
        return true;
      }
      auto info = job_->select(name);
      if (!info) {
        reply = "echo:open failed, File: " + name + ". (" + info.error().message + ")\nok";
        return true;
      }
      if (Status s = job_->set_start_byte(start_byte); !s) {
        fail(s.error().message);
        return true;
      }
      if (Status s = job_start("", client_id); !s) {
        fail(s.error().message);
        return true;
      }
      reply = opened(*info) + "ok";
      return true;
    }
    case 524:  // M524: abort the print
      if (Status s = job_cancel(); !s)
        fail(s.error().message);
      else
        reply = "ok";
      return true;
    default:
      return false;
  }
}

}  // namespace feedloop::daemon
