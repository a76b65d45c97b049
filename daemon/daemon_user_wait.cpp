// M0 / M1 / M600 from a Marlin client: the machine stops for the user, and the host's answer (M108
// or M876) lets the client's lines go on. Marlin's forms: M0 / M1 (gcode/lcd/M0_M1.cpp: the
// planner is synchronised, the text shown, a host prompt offered with HOST_PROMPT_SUPPORT, and the
// queue waits for a click, an M108 or an M876); M600 (gcode/feature/pause/M600.cpp and
// feature/pause.cpp: pause_print retracts, raises Z and parks, the user loads the filament,
// resume_print returns over XY, then Z, and primes). In a print job the same commands pause the
// job (print_job.cpp); this is the streaming host's side of them.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <iterator>
#include <memory>
#include <string_view>

#include "daemon/daemon.hpp"
#include "gcode/parser.hpp"

namespace feedloop::daemon {

bool Daemon::is_user_stop(const gcode::Command& cmd) {
  if (cmd.letter != 'M' || cmd.subcode >= 0) return false;
  if (cmd.code == 600) return true;
  // M0 / M1 with P<ms> or S<s> wait that long and go on (process_marlin_line dwells).
  return (cmd.code == 0 || cmd.code == 1) && !cmd.has('P') && !cmd.has('S');
}

void Daemon::begin_user_wait(Client& c, const gcode::Command& cmd, std::string_view line) {
  UserWait w;
  w.slot = std::make_shared<ReplySlot>();
  w.filament_change = cmd.code == 600;
  w.message = w.filament_change  ? std::string("filament change (M600): load the new filament")
              : cmd.text.empty() ? "M" + std::to_string(cmd.code) + " stop"
                                 : cmd.text;
  c.replies.push_back(w.slot);
  c.user_wait = std::move(w);
  // The client's next lines wait in its session until the answer (which is seen as it arrives).
  c.session->pause_reading();
  gcode::Command synchronise;  // Marlin's planner.synchronize(): every command before has run
  synchronise.letter = 'M';
  synchronise.code = 400;
  const uint64_t cid = c.id;
  const auto source = c.session->name().rfind("pty", 0) == 0 ? recorder::GcodeSource::pty
                                                             : recorder::GcodeSource::socket;
  const std::string refused =
      submit(c, synchronise, line, source,
             [this, cid](const Status& st, const std::string&) { on_user_wait_stopped(cid, st); });
  if (!refused.empty()) end_user_wait(c, Error{refused, {}});
}

void Daemon::on_user_wait_stopped(uint64_t client_id, const Status& st) {
  Client* c = find_client(client_id);
  if (!c || !c->user_wait) return;
  if (!st) {
    end_user_wait(*c, st);
    return;
  }
  auto announce = [this](Client& cl) {
    UserWait& w = *cl.user_wait;
    w.waiting = true;
    flush_replies(cl);  // the answers of the lines before the stop
    display_message_ = w.message;
    snapshot_.stale = true;
    cl.session->send_line("echo:" + w.message + "; send M108 to continue");
    // Marlin's host prompt (HOST_PROMPT_SUPPORT): OctoPrint and Pronterface show a button, which
    // answers M876 S0.
    cl.session->send_line("//action:prompt_end");
    cl.session->send_line("//action:prompt_begin " + w.message);
    cl.session->send_line("//action:prompt_button Continue");
    cl.session->send_line("//action:prompt_show");
    cl.last_progress_ns = clock_.now_ns();
    spdlog::info("{}: {}; waiting for M108 or M876", cl.session->name(), w.message);
  };
  UserWait& w = *c->user_wait;
  if (!w.filament_change) {
    announce(*c);
    return;
  }
  // M600: retract (a hot nozzle), raise Z within its travel, park in XY (the job's pause settings,
  // config jobs:), and remember the way back with the host's modes.
  const engine::MachineStatus s = machine_->status();
  const std::string_view homed = s.homed_axes;
  const bool all_homed = homed.find('x') != std::string_view::npos &&
                         homed.find('y') != std::string_view::npos &&
                         homed.find('z') != std::string_view::npos;
  if (!all_homed && !cfg_.planner.allow_moves_before_homing) {  // the park would be refused midway
    end_user_wait(*c, Error{"M600: the axes are not homed (send G28 first); nothing moved", {}});
    return;
  }
  const JobOptions o = pause_options();
  w.retracted = engine::can_extrude(s) && o.pause_retract_mm > 0.0;
  std::copy(std::begin(s.pos_mm), std::end(s.pos_mm), std::begin(w.parked_from_mm));
  w.restore_lines = {s.absolute_coordinates ? "G90" : "G91", s.absolute_extrude ? "M82" : "M83"};
  if (s.feedrate_mm_s > 0.0)
    w.restore_lines.push_back("G1 F" + std::to_string(s.feedrate_mm_s * 60.0));
  if (s.inches) w.restore_lines.push_back("G20");  // the park and the way back are in millimetres
  std::vector<std::string> park = park_moves(o, s.pos_mm, w.retracted);
  run_lines(client_id, std::move(park), 0, [this, client_id, announce](const Status& parked) {
    Client* cl = find_client(client_id);
    if (!cl || !cl->user_wait) return;
    if (!parked) {
      end_user_wait(*cl, parked);
      return;
    }
    announce(*cl);
  });
}

bool Daemon::user_waiting() const {
  for (const auto& [id, c] : clients_)
    if (c.user_wait && c.user_wait->waiting) return true;
  return false;
}

void Daemon::on_user_answer() {
  std::vector<uint64_t> answered;
  for (auto& [id, c] : clients_)
    if (c.user_wait && c.user_wait->waiting) answered.push_back(id);
  for (const uint64_t id : answered) {
    Client* c = find_client(id);
    if (!c || !c->user_wait) continue;
    UserWait& w = *c->user_wait;
    w.waiting = false;
    c->session->send_line("//action:prompt_end");
    spdlog::info("{}: the user answered ({})", c->session->name(), w.message);
    if (!w.filament_change) {
      end_user_wait(*c, Status::Ok());
      continue;
    }
    // The retract back, and the prime beyond it when the nozzle is hot (as a job's resume).
    const JobOptions o = pause_options();
    const double push = (w.retracted ? o.pause_retract_mm : 0.0) +
                        (engine::can_extrude(machine_->status()) ? o.prime_extra_mm : 0.0);
    std::vector<std::string> back = {"G21", "G90"};
    for (std::string& line : return_moves(o, w.parked_from_mm, push))
      back.push_back(std::move(line));
    back.insert(back.end(), w.restore_lines.begin(), w.restore_lines.end());
    run_lines(id, std::move(back), 0, [this, id](const Status& st) {
      if (Client* cl = find_client(id); cl && cl->user_wait) end_user_wait(*cl, st);
    });
  }
}

void Daemon::end_user_wait(Client& c, const Status& st) {
  const UserWait w = std::move(*c.user_wait);
  c.user_wait.reset();
  if (display_message_ == w.message) display_message_.clear();
  snapshot_.stale = true;
  w.slot->text = st ? std::string() : "Error:" + st.error().to_string() + "\n";
  w.slot->text += gcode::HostProtocol::kOk;
  w.slot->ready = true;
  c.last_progress_ns = clock_.now_ns();
  flush_replies(c);
  drain_backlog(c);
}

void Daemon::run_lines(uint64_t client_id, std::vector<std::string> lines, size_t next,
                       std::function<void(const Status&)> done) {
  Client* c = find_client(client_id);
  if (!c) return;
  if (next >= lines.size()) {
    done(Status::Ok());
    return;
  }
  const std::string text = lines[next];
  auto cmd = gcode::parse_line(text, SourceLocation{"M600", static_cast<int>(next + 1), 0});
  if (!cmd) {
    done(cmd.error());
    return;
  }
  auto rest = std::make_shared<std::vector<std::string>>(std::move(lines));
  const std::string refused =
      submit(*c, *cmd, text, recorder::GcodeSource::api,
             [this, client_id, rest, next, done](const Status& st, const std::string&) {
               if (!st) {
                 done(st);
                 return;
               }
               run_lines(client_id, std::move(*rest), next + 1, done);
             });
  if (!refused.empty()) done(Error{refused, {}});
}

}  // namespace feedloop::daemon
