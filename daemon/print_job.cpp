#include "daemon/print_job.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "core/utf8.hpp"
#include "gcode/file_kind.hpp"
#include "gcode/parser.hpp"

namespace feedloop::daemon {

const char* to_string(JobState s) {
  switch (s) {
    case JobState::kIdle:
      return "idle";
    case JobState::kReady:
      return "ready";
    case JobState::kPrinting:
      return "printing";
    case JobState::kPausing:
      return "pausing";
    case JobState::kPaused:
      return "paused";
    case JobState::kResuming:
      return "resuming";
    case JobState::kCancelling:
      return "cancelling";
    case JobState::kComplete:
      return "complete";
    case JobState::kCancelled:
      return "cancelled";
    case JobState::kError:
      return "error";
  }
  return "unknown";
}

namespace {
constexpr size_t kMaxLineBytes = 4096;  // a longer line is an error (the sockets' limit is 1024)

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}
// Numbers for generated G-code: enough digits for one encoder count, no exponent.
std::string num(double v) {
  return fmt("%.5f", v);
}

constexpr size_t npos = std::string_view::npos;

// A pause that the file itself asks for (feed()): which command, and the job's message.
struct FilePause {
  bool pauses = false;
  std::string message;
};

// The free text after a line's command code ("M0 Insert the magnets ; at 5 mm" -> "Insert the
// magnets"), up to a comment or a checksum, at most 120 bytes, valid UTF-8 (it reaches JSON).
std::string text_after_code(std::string_view line) {
  size_t i = line.find_first_of("Mm");
  if (i == npos) return {};
  ++i;
  while (i < line.size() && std::isdigit(static_cast<unsigned char>(line[i]))) ++i;
  std::string_view rest = line.substr(i);
  rest = rest.substr(0, rest.find_first_of(";*"));
  const auto not_space = [](char c) { return c != ' ' && c != '\t' && c != '\r'; };
  const auto b = std::find_if(rest.begin(), rest.end(), not_space);
  const auto e = std::find_if(rest.rbegin(), rest.rend(), not_space).base();
  rest = b < e ? std::string_view(&*b, static_cast<size_t>(e - b)) : std::string_view{};
  return valid_utf8(rest.substr(0, 120));
}

// Marlin's M25 (SD pause), M601 (PrusaSlicer's pause print), M600 (filament change; Marlin
// parks, unloads and waits: here the job's pause parks and holds the heaters) and M0 / M1
// (unconditional stop, Cura's pause at height: Marlin waits for a click and shows the text).
// M0 / M1 with P<ms> or S<s> first wait that long in Marlin and go on: not a pause (feed()
// dwells).
FilePause pause_in_file(const gcode::Command& c, std::string_view line) {
  if (c.letter != 'M') return {};
  switch (c.code) {
    case 25:
    case 601:
      return {true, "paused by M" + std::to_string(c.code) + " in the file"};
    case 600:
      return {true, "filament change (M600): load the new filament"};
    case 0:
    case 1: {
      const std::string text = text_after_code(line);
      const bool timed = text.size() >= 2 && std::string_view("PpSs").find(text[0]) != npos &&
                         std::string_view("0123456789.+-").find(text[1]) != npos;
      if (timed) return {};
      return {true, "paused by M" + std::to_string(c.code) + (text.empty() ? "" : ": " + text)};
    }
    default:
      return {};
  }
}
}  // namespace

PrintJob::PrintJob(JobFiles& files, JobOptions options, JobSink& sink)
    : files_(files), options_(options), sink_(sink), alive_(std::make_shared<bool>(true)) {}

PrintJob::~PrintJob() {
  *alive_ = false;
  close_file();
}

bool PrintJob::active() const {
  return state_ == JobState::kPrinting || state_ == JobState::kPausing ||
         state_ == JobState::kPaused || state_ == JobState::kResuming ||
         state_ == JobState::kCancelling;
}

Result<JobFileInfo> PrintJob::select(std::string_view name) {
  if (active())
    return Error{"a print job is active ('" + file_ + "', " + to_string(state_) +
                 "): cancel it first"};
  auto info = files_.stat(name);
  if (!info) return info.error();
  // A compressed file or binary G-code would run as thousands of refused lines: refused here.
  if (std::FILE* f = std::fopen(files_.path_of(info->name).c_str(), "rb")) {
    char head[8] = {};
    const size_t got = std::fread(head, 1, sizeof head, f);
    std::fclose(f);
    if (auto kind = gcode::non_gcode_file_kind(std::string_view(head, got)))
      return Error{"'" + info->name + "' is " + *kind};
  }
  close_file();
  file_ = info->name;
  size_ = info->size_bytes;
  start_byte_ = 0;
  state_ = JobState::kReady;
  message_.clear();
  return info;
}

Status PrintJob::clear() {
  if (active())
    return Error{"a print job is active ('" + file_ + "', " + to_string(state_) +
                 "): cancel it first"};
  close_file();
  file_.clear();
  size_ = 0;
  start_byte_ = 0;
  bytes_submitted_ = 0;
  filament_used_mm_ = 0.0;
  message_.clear();
  state_ = JobState::kIdle;
  return Status::Ok();
}

Status PrintJob::set_start_byte(uint64_t byte) {
  if (state_ != JobState::kReady)
    return Error{"no file selected, or the job has started (M26 needs M23 first)"};
  if (byte > size_)
    return Error{"position " + std::to_string(byte) + " is past the end of '" + file_ + "' (" +
                 std::to_string(size_) + " bytes)"};
  start_byte_ = byte;
  return Status::Ok();
}

Status PrintJob::open_file(uint64_t start_byte) {
  close_file();
  const std::string path = files_.path_of(file_);
  fp_ = std::fopen(path.c_str(), "rb");
  if (!fp_) return Error{"cannot open job file '" + file_ + "': " + std::strerror(errno)};
  read_offset_ = 0;
  line_number_ = 0;
  eof_ = false;
  read_error_.clear();
  if (start_byte > 0) {
    // M26 S: Marlin seeks to the byte; a byte inside a line skips the rest of that line here, so
    // no half command is ever executed.
    if (std::fseek(fp_, static_cast<long>(start_byte - 1), SEEK_SET) != 0)
      return Error{"cannot seek in '" + file_ + "': " + std::strerror(errno)};
    read_offset_ = start_byte - 1;
    const int c = std::fgetc(fp_);
    ++read_offset_;
    if (c != '\n' && c != EOF) read_line();  // the partial line
    line_number_ = 0;                        // unknown after a seek: lines count from here
  }
  return Status::Ok();
}

void PrintJob::close_file() {
  if (fp_) std::fclose(fp_);
  fp_ = nullptr;
}

bool PrintJob::read_line() {
  line_.clear();
  if (!fp_ || eof_) return false;
  bool any = false;
  for (;;) {
    const int c = std::fgetc(fp_);
    if (c == EOF) {
      // A read error (a removed USB stick, EIO) is not the file's end: the job fails, naming it,
      // rather than completing without the rest of the file.
      if (std::ferror(fp_)) read_error_ = std::strerror(errno);
      eof_ = true;
      break;
    }
    any = true;
    ++read_offset_;
    if (c == '\n') break;
    if (line_.size() <= kMaxLineBytes) line_.push_back(static_cast<char>(c));
  }
  if (!any) return false;
  ++line_number_;
  if (!line_.empty() && line_.back() == '\r') line_.pop_back();
  return true;
}

Status PrintJob::start(std::string_view name) {
  if (active())
    return Error{"a print job is active ('" + file_ + "', " + to_string(state_) +
                 "): cancel it first"};
  if (!name.empty()) {
    auto info = select(name);
    if (!info) return info.error();
  }
  if (file_.empty() || state_ == JobState::kIdle) return Error{"no file selected"};
  if (state_ != JobState::kReady) {  // a finished job: run its file again from the top
    auto info = select(std::string(file_));
    if (!info) return info.error();
  }
  if (Status s = open_file(start_byte_); !s) return s;
  const engine::MachineStatus ms = sink_.machine_status();
  print_time_start_s_ = ms.planned_until_s;
  filament_used_mm_ = 0.0;
  file_e_mm_ = ms.pos_mm[3];
  planned_at_last_submit_s_ = ms.planned_until_s;
  excluded_print_time_s_ = 0.0;
  bytes_submitted_ = start_byte_;
  lines_submitted_ = 0;
  in_flight_ = 0;
  held_.reset();
  sequence_.clear();
  phase_ = Phase::kNone;
  modes_ = Modes{};
  pause_pos_ = JobPosition{};
  resume_pos_ = JobPosition{};
  cancel_after_pause_ = false;
  resume_after_pause_ = false;
  parked_ = false;
  retracted_ = false;
  reset_objects_ = sink_.has_object_labels();
  message_.clear();
  started_ns_ = sink_.now_ns();
  ended_ns_ = 0;
  paused_total_ns_ = 0;
  pauses_ = 0;
  state_ = JobState::kPrinting;
  pump();
  return Status::Ok();
}

Status PrintJob::pause() {
  if (state_ == JobState::kPaused || state_ == JobState::kPausing)
    return Status::Ok();  // M25 twice: no-op
  if (state_ != JobState::kPrinting)
    return Error{std::string("no print to pause (job ") + to_string(state_) + ")"};
  state_ = JobState::kPausing;
  phase_ = Phase::kPauseWait;
  ++pauses_;
  paused_since_ns_ = sink_.now_ns();
  pump();
  return Status::Ok();
}

Status PrintJob::resume() {
  if (state_ == JobState::kResuming || state_ == JobState::kPrinting) return Status::Ok();
  if (state_ == JobState::kPausing) {
    // A UI shows "paused" as soon as it asked (Klipper's print_stats does): a resume while the
    // head still parks returns once parked (the pause position is taken first).
    resume_after_pause_ = !cancel_after_pause_;
    return Status::Ok();
  }
  if (state_ != JobState::kPaused)
    return Error{std::string("no paused print to resume (job ") + to_string(state_) + ")"};
  const engine::MachineStatus now = sink_.machine_status();
  if (parked_ && retracted_ && !engine::can_extrude(now)) {
    // The pause retracted the filament; priming it back needs a hot nozzle. Refused whole: the
    // job stays paused where it was (Marlin's resume heats the nozzle first; here the user does).
    char why[200];
    std::snprintf(why, sizeof why,
                  "cannot resume: the hotend is at %.1f C, below min_extrude_temp %.0f C, and the "
                  "pause retracted the filament; heat it (M109 S<temp>) and resume",
                  now.hotend_c, now.min_extrude_temp_c);
    return Error{why};
  }
  state_ = JobState::kResuming;
  phase_ = Phase::kResumeBack;
  message_.clear();  // a pause's message from the file ("filament change (M600): ...")
  const JobPosition& p = pause_pos_;
  add_sequence("G21");
  add_sequence("G90");
  if (parked_) {
    // The retract back, and the prime beyond it when the nozzle is hot (a pause of a cold
    // hotend retracted nothing).
    const double push = (retracted_ ? options_.pause_retract_mm : 0.0) +
                        (engine::can_extrude(now) ? options_.prime_extra_mm : 0.0);
    for (std::string& line : return_moves(options_, p.pos_mm, push)) add_sequence(std::move(line));
  }
  add_sequence("G4 P" + std::to_string(options_.settle_ms));
  add_sequence("M400");
  pump();
  return Status::Ok();
}

Status PrintJob::cancel() {
  if (!active()) return Error{std::string("no print to cancel (job ") + to_string(state_) + ")"};
  if (state_ == JobState::kCancelling) return Status::Ok();
  if (state_ == JobState::kPaused || state_ == JobState::kPausing)
    paused_total_ns_ += sink_.now_ns() - paused_since_ns_;
  // Resuming: partly back over the part; pausing: the park may be cut short. Park again.
  if (state_ == JobState::kResuming || state_ == JobState::kPausing) parked_ = false;
  cancel_after_pause_ = false;
  resume_after_pause_ = false;
  message_.clear();  // a pause's message from the file no longer applies
  // At once (Klipper's CANCEL_PRINT, Marlin's M524): heaters off and the queued commands dropped
  // now, not behind up to a queue of moves. While paused the job has nothing queued and another
  // client may be moving the machine: heaters off only.
  const bool paused = state_ == JobState::kPaused;
  state_ = JobState::kCancelling;
  phase_ = Phase::kCancelWait;
  sequence_.clear();  // a resume in progress is dropped with the queue
  held_.reset();
  // (The dropped commands' completions may come back from inside cancel_motion: the state is set.)
  if (paused)
    sink_.all_heaters_off();
  else
    sink_.cancel_motion();
  pump();
  return Status::Ok();
}

void PrintJob::add_sequence(std::string line) {
  sequence_.push_back(std::move(line));
}

std::function<void(const Status&)> PrintJob::completion(bool from_file, int64_t line,
                                                        std::string text) {
  std::weak_ptr<bool> alive = alive_;
  return [this, alive, from_file, line, text = std::move(text)](const Status& st) {
    auto a = alive.lock();
    if (!a || !*a) return;
    if (in_flight_ > 0) --in_flight_;
    if (!st && state_ == JobState::kCancelling && phase_ == Phase::kCancelWait) {
      // Dropped by the cancel's flush (or cut short by it): nothing to report.
    } else if (!st) {
      if (from_file) {
        // The machine's error names the line already when it carries the command's location.
        const Error& e = st.error();
        const bool located = e.where.source == file_ && e.where.line == line;
        fail(located ? e.to_string() : file_ + ":" + std::to_string(line) + ": " + e.to_string());
      } else {
        // A refused move of the job's own (e.g. a park point outside the travel): reported, the
        // sequence goes on (the nozzle stays where it is).
        message_ = "'" + text + "': " + st.error().to_string();
      }
    }
    pump();
  };
}

void PrintJob::track_extrusion(const gcode::Command& c) {
  if (c.letter != 'G' || !c.has('E')) return;
  const double e_mm = c.get('E') * (modes_.inches ? 25.4 : 1.0);
  if (c.code == 92) {
    file_e_mm_ = e_mm;
    return;
  }
  if (c.code > 3) return;
  const bool relative = modes_.e_mode == 2 || (modes_.e_mode == 0 && modes_.relative_xyz);
  filament_used_mm_ += relative ? e_mm : e_mm - file_e_mm_;
  file_e_mm_ = relative ? file_e_mm_ + e_mm : e_mm;
}

void PrintJob::track_modes(const gcode::Command& c) {
  if (c.letter == 'G') {
    if (c.code == 90 || c.code == 91) {
      modes_.relative_xyz = c.code == 91;
      modes_.e_mode = 0;  // Marlin: G90/G91 also set E's mode
    } else if (c.code == 20 || c.code == 21) {
      modes_.inches = c.code == 20;
    } else if (c.code <= 3 && c.has('F')) {
      modes_.feed_units_min = c.get('F');
    }
  } else if (c.letter == 'M' && (c.code == 82 || c.code == 83)) {
    modes_.e_mode = c.code == 82 ? 1 : 2;
  } else if (c.is('M', 486) && !c.unknown && c.subcode == gcode::kObjectStart) {
    modes_.object = c.text;
  } else if (c.is('M', 486) && !c.unknown && c.subcode == gcode::kObjectName && c.has('S')) {
    modes_.object = planner::ObjectLabels::index_name(c.get('S'));  // RepRapFirmware's start
  } else if (c.is('M', 486) && !c.unknown && c.subcode == gcode::kObjectEnd) {
    modes_.object.clear();
  }
}

void PrintJob::feed() {
  for (int n = 0; n < options_.lines_per_pump && state_ == JobState::kPrinting; ++n) {
    if (options_.read_ahead_s > 0.0) {
      const engine::MachineStatus ms = sink_.machine_status();
      if (ms.moving && ms.planned_until_s - ms.print_time_s > options_.read_ahead_s) return;
    }
    if (reset_objects_) {
      // A new print's objects: none labelled, none excluded (Klipper resets exclude_object when a
      // print starts): an object excluded in the last print is not skipped in this one.
      static constexpr const char* kReset = "EXCLUDE_OBJECT_DEFINE RESET=1";
      const auto reset = gcode::parse_line(kReset, SourceLocation{"job", 0, 0});
      std::string why;
      const auto offer = reset ? sink_.offer(*reset, kReset, completion(false, 0, kReset), &why)
                               : JobSink::Offer::kRefused;
      if (offer == JobSink::Offer::kFull) return;
      reset_objects_ = false;
      if (offer == JobSink::Offer::kRefused) {
        fail(file_ + ": the print's object labels could not be reset: " + why);
        return;
      }
      ++in_flight_;
    }
    if (!held_) {
      if (!read_line()) {
        if (!read_error_.empty())
          fail(file_ + ": read error after line " + std::to_string(line_number_) + " (byte " +
               std::to_string(read_offset_) + "): " + read_error_);
        return;
      }
      if (line_.size() > kMaxLineBytes) {
        fail(file_ + ":" + std::to_string(line_number_) + ": line longer than " +
             std::to_string(kMaxLineBytes) + " bytes");
        return;
      }
      auto cmd = gcode::parse_line(line_, SourceLocation{file_, static_cast<int>(line_number_), 0});
      if (!cmd) {
        fail(cmd.error().to_string());
        return;
      }
      if (cmd->empty()) {  // blank or comment: nothing to execute
        bytes_submitted_ = read_offset_;
        continue;
      }
      if (const FilePause fp = pause_in_file(*cmd, line_); fp.pauses) {
        // A pause in the file (Marlin's M25 in an SD print; M601, PrusaSlicer's pause print;
        // M600, the slicers' filament change; M0 / M1, Cura's pause at height): the job pauses
        // itself there, parked with the heaters held, and resume goes on with the next line.
        bytes_submitted_ = read_offset_;
        (void)pause();  // printing: it cannot fail
        message_ =
            fp.message + " (" + file_ + ":" + std::to_string(line_number_) + "); resume to go on";
        return;
      }
      if (cmd->is('M', 0) || cmd->is('M', 1)) {
        // M0 / M1 with P or S: Marlin waits that long for a click and goes on; with no panel to
        // click, a dwell (pause_in_file took the forms without).
        const double ms = cmd->has('P') ? cmd->get('P') : 1000.0 * cmd->get('S');
        cmd->clear();
        cmd->letter = 'G';
        cmd->code = 4;
        cmd->set('P', std::max(0.0, ms));
      }
      held_ = std::move(*cmd);
      held_text_ = line_;
      held_line_ = line_number_;
      held_end_offset_ = read_offset_;
    }
    std::string why;
    const auto offer = sink_.offer(*held_, held_text_, completion(true, held_line_, {}), &why);
    if (offer == JobSink::Offer::kFull) return;  // the machine's queue is full: next pump
    if (offer == JobSink::Offer::kRefused) {
      fail(file_ + ":" + std::to_string(held_line_) + ": " + why);
      return;
    }
    ++in_flight_;
    track_extrusion(*held_);
    track_modes(*held_);
    bytes_submitted_ = held_end_offset_;
    ++lines_submitted_;
    held_.reset();
    planned_at_last_submit_s_ = sink_.machine_status().planned_until_s;
  }
}

void PrintJob::send_sequence() {
  while (!sequence_.empty()) {
    const std::string& text = sequence_.front();
    auto cmd =
        gcode::parse_line(text, SourceLocation{"job", static_cast<int>(++sequence_number_), 0});
    if (!cmd) {  // cannot happen for the lines built here; reported rather than trusted
      message_ = cmd.error().to_string();
      sequence_.pop_front();
      continue;
    }
    std::string why;
    const auto offer = sink_.offer(*cmd, text, completion(false, 0, text), &why);
    if (offer == JobSink::Offer::kFull) return;
    if (offer == JobSink::Offer::kRefused) {
      message_ = "'" + text + "': " + why;
      sequence_.clear();
      if (state_ != JobState::kError) finish(JobState::kError);
      return;
    }
    ++in_flight_;
    sequence_.pop_front();
  }
}

void PrintJob::pump() {
  pump_once();
  report_input();
}

void PrintJob::report_input() {
  const bool coming = state_ == JobState::kPrinting && (held_.has_value() || !eof_);
  if (coming != input_coming_) sink_.set_input_coming(coming);
  input_coming_ = coming;
}

void PrintJob::pump_once() {
  if (!active()) return;
  if (state_ == JobState::kPrinting) {
    // A machine that faulted (following error, encoder, MCU) or was stopped runs nothing more: the
    // job ends in error with the machine's reason, instead of printing forever.
    if (const engine::MachineStatus m = sink_.machine_status();
        m.state == engine::MachineState::kError ||
        m.state == engine::MachineState::kEmergencyStopped) {
      fail(std::string("the machine stopped: ") +
           (m.last_error[0] != '\0' ? m.last_error : "emergency stop"));
      return;
    }
    feed();
    if (state_ == JobState::kPrinting && eof_ && !held_ && in_flight_ == 0 &&
        sink_.machine_status().state == engine::MachineState::kIdle)
      finish(JobState::kComplete);
    return;
  }
  send_sequence();
  if (!sequence_.empty() || in_flight_ > 0 || phase_ == Phase::kNone) return;
  on_phase_done();
}

JobPosition PrintJob::take_position() const {
  const engine::MachineStatus s = sink_.machine_status();
  JobPosition p;
  p.valid = true;
  for (int i = 0; i < 4; ++i) {
    p.pos_mm[i] = s.pos_mm[i];
    p.step_count[i] = s.step_count[i];
    p.encoder_mm[i] = s.encoder_mm[i];
  }
  return p;
}

void PrintJob::park_lines(const engine::MachineStatus& at, bool retract) {
  for (std::string& line : park_moves(options_, at.pos_mm, retract)) add_sequence(std::move(line));
}

void PrintJob::on_phase_done() {
  switch (phase_) {
    case Phase::kPauseWait:
      // The file's queued commands have executed; their motion ends, then the machine stands
      // still for the settle dwell (a G4 right after motion is part of it: the loops hold the
      // carriages through it), as on the resume's side.
      exclude_from_s_ = -1.0;
      phase_ = Phase::kPauseSettled;
      add_sequence("G4 P" + std::to_string(options_.settle_ms));
      add_sequence("M400");
      pump();
      return;
    case Phase::kPauseSettled: {
      pause_pos_ = take_position();
      saved_modes_ = modes_;
      const engine::MachineStatus s = sink_.machine_status();
      exclude_from_s_ = s.planned_until_s;
      phase_ = Phase::kPauseParked;
      // Paused inside a labelled object: the park (and the resume's way back) must move even
      // when that object is excluded; the resume enters it again (kResumeBack).
      if (!saved_modes_.object.empty()) add_sequence("EXCLUDE_OBJECT_END");
      // Marlin's pause retracts only a hotend hot enough to extrude (a cold one would refuse it).
      retracted_ = engine::can_extrude(s);
      park_lines(s, retracted_);
      parked_ = true;
      pump();
      return;
    }
    case Phase::kPauseParked:
      phase_ = Phase::kNone;
      state_ = JobState::kPaused;
      if (resume_after_pause_) {
        resume_after_pause_ = false;
        // Paused: it fails only when the nozzle it would prime has gone cold (then it says so).
        if (Status st = resume(); !st) message_ = st.error().to_string();
        return;
      }
      if (cancel_after_pause_) {
        cancel_after_pause_ = false;
        (void)cancel();  // paused and active: it cannot fail
      }
      return;
    case Phase::kResumeBack: {
      resume_pos_ = take_position();
      const engine::MachineStatus s = sink_.machine_status();
      if (exclude_from_s_ >= 0.0) excluded_print_time_s_ += s.planned_until_s - exclude_from_s_;
      exclude_from_s_ = -1.0;
      // Klipper's RESTORE_GCODE_STATE: the modes and the feedrate the file left.
      phase_ = Phase::kResumeDone;
      add_sequence(saved_modes_.relative_xyz ? "G91" : "G90");
      if (saved_modes_.e_mode == 1) add_sequence("M82");
      if (saved_modes_.e_mode == 2) add_sequence("M83");
      if (saved_modes_.inches) add_sequence("G20");
      if (saved_modes_.feed_units_min) add_sequence("G1 F" + num(*saved_modes_.feed_units_min));
      if (!saved_modes_.object.empty()) {
        const char q = saved_modes_.object.find('\'') == std::string::npos ? '\'' : '"';
        add_sequence("EXCLUDE_OBJECT_START NAME=" + std::string(1, q) + saved_modes_.object + q);
      }
      pump();
      return;
    }
    case Phase::kResumeDone:
      phase_ = Phase::kNone;
      parked_ = false;
      paused_total_ns_ += sink_.now_ns() - paused_since_ns_;
      state_ = JobState::kPrinting;
      pump();
      return;
    case Phase::kCancelWait: {
      // Everything of the file that was queued has executed: heaters off behind it, then park.
      sink_.all_heaters_off();
      phase_ = Phase::kCancelParked;
      if (!modes_.object.empty()) add_sequence("EXCLUDE_OBJECT_END");  // the park moves
      if (!parked_) {
        const engine::MachineStatus s = sink_.machine_status();
        park_lines(s, engine::can_extrude(s));
      }
      parked_ = true;
      pump();
      return;
    }
    case Phase::kCancelParked:
      phase_ = Phase::kNone;
      finish(JobState::kCancelled);
      return;
    case Phase::kNone:
      return;
  }
}

void PrintJob::fail(const std::string& message) {
  if (!active()) return;
  message_ = message;
  held_.reset();
  sequence_.clear();
  sink_.all_heaters_off();
  finish(JobState::kError);
}

void PrintJob::finish(JobState end) {
  if (state_ == JobState::kPaused) paused_total_ns_ += sink_.now_ns() - paused_since_ns_;
  state_ = end;
  phase_ = Phase::kNone;
  ended_ns_ = sink_.now_ns();
  close_file();
  report_input();
}

double PrintJob::job_print_time_s(const engine::MachineStatus& s) const {
  double excluded = excluded_print_time_s_;
  if (exclude_from_s_ >= 0.0) excluded += std::max(0.0, s.print_time_s - exclude_from_s_);
  return std::max(0.0, s.print_time_s - print_time_start_s_ - excluded);
}

JobStatus PrintJob::status() const {
  JobStatus j;
  j.state = state_;
  j.file = file_;
  j.size_bytes = size_;
  j.bytes_submitted = bytes_submitted_;
  j.lines_submitted = lines_submitted_;
  j.lines_read = static_cast<uint64_t>(std::max<int64_t>(0, line_number_));
  j.pauses = pauses_;
  j.filament_used_mm = filament_used_mm_;
  j.message = message_;
  j.pause_position = pause_pos_;
  j.resume_position = resume_pos_;
  if (state_ == JobState::kIdle || state_ == JobState::kReady) return j;
  j.progress_bytes =
      size_ > 0 ? static_cast<double>(bytes_submitted_) / static_cast<double>(size_) : 1.0;
  const int64_t now = ended_ns_ != 0 ? ended_ns_ : sink_.now_ns();
  j.elapsed_s = static_cast<double>(now - started_ns_) * 1e-9;
  int64_t paused = paused_total_ns_;
  if (state_ == JobState::kPaused || state_ == JobState::kResuming || state_ == JobState::kPausing)
    paused += now - paused_since_ns_;
  j.paused_s = static_cast<double>(paused) * 1e-9;
  if (state_ == JobState::kComplete) {
    j.progress_bytes = 1.0;
  }
  const engine::MachineStatus s = sink_.machine_status();
  j.print_time_s = job_print_time_s(s);
  // The planner's estimate: the print time planned for the bytes handed over so far, scaled to
  // the whole file (the rest of the file is assumed to print at the same time per byte).
  const double planned_s =
      std::max(0.0, planned_at_last_submit_s_ - print_time_start_s_ - excluded_print_time_s_);
  const double bytes_done =
      static_cast<double>(bytes_submitted_ - std::min(bytes_submitted_, start_byte_));
  const double bytes_all = static_cast<double>(size_ - std::min(size_, start_byte_));
  if (state_ == JobState::kComplete) {
    j.estimated_total_s = j.print_time_s;
  } else if (bytes_done > 0.0 && planned_s > 0.0) {
    j.estimated_total_s = std::max(planned_s * bytes_all / bytes_done, j.print_time_s);
  }
  j.estimated_remaining_s = std::max(0.0, j.estimated_total_s - j.print_time_s);
  j.progress_time =
      j.estimated_total_s > 0.0 ? std::min(1.0, j.print_time_s / j.estimated_total_s) : 0.0;
  return j;
}

std::vector<std::string> park_moves(const JobOptions& o, const double at_mm[4], bool retract) {
  std::vector<std::string> lines = {"G21"};
  if (retract && o.pause_retract_mm > 0.0) {
    lines.push_back("G91");
    lines.push_back("G1 E" + num(-o.pause_retract_mm) + " F" + num(o.retract_speed_mm_s * 60.0));
  }
  lines.push_back("G90");
  // Marlin's nozzle park: Z up by the raise, never above Z's travel (NOZZLE_PARK_Z_RAISE_MIN).
  const double z = std::min(at_mm[2] + o.lift_mm, o.z_max_mm);
  if (z > at_mm[2]) lines.push_back("G1 Z" + num(z) + " F" + num(o.z_speed_mm_s * 60.0));
  if (o.park_x_mm || o.park_y_mm) {
    std::string move = "G1";
    if (o.park_x_mm) move += " X" + num(*o.park_x_mm);
    if (o.park_y_mm) move += " Y" + num(*o.park_y_mm);
    lines.push_back(move + " F" + num(o.travel_speed_mm_s * 60.0));
  }
  lines.push_back("M400");
  return lines;
}

std::vector<std::string> return_moves(const JobOptions& o, const double to_mm[4], double push_mm) {
  // Marlin's resume_print (feature/pause.cpp): back over the part in XY, then down, then prime.
  // Inside the travel: a pause right after a homing found the head past the limit by the halt's
  // overshoot; the next move goes on from there.
  const double x = std::clamp(to_mm[0], o.x_min_mm, o.x_max_mm);
  const double y = std::clamp(to_mm[1], o.y_min_mm, o.y_max_mm);
  std::vector<std::string> lines = {
      "G1 X" + num(x) + " Y" + num(y) + " F" + num(o.travel_speed_mm_s * 60.0),
      "G1 Z" + num(to_mm[2]) + " F" + num(o.z_speed_mm_s * 60.0)};
  if (push_mm > 0.0) {
    lines.push_back("G91");
    lines.push_back("G1 E" + num(push_mm) + " F" + num(o.retract_speed_mm_s * 60.0));
    lines.push_back("G90");
  }
  lines.push_back("G92 E" + num(to_mm[3]));
  return lines;
}

}  // namespace feedloop::daemon
