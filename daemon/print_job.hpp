// The print job controller (issue 16): the daemon itself reads a file of the job folder line by
// line and hands each line to the same line path the clients use (one G-code path), paced by the
// machine's queue: a line the queue cannot take now is kept and offered again at the next pump,
// so nothing here ever blocks (the daemon pumps on its 5 ms tick and after each completion).
//
// States: idle (no file) -> ready (selected: M23) -> printing -> pausing -> paused -> resuming ->
// printing ... -> complete | cancelled | error. Pause follows Marlin's M25 with
// PARK_HEAD_ON_PAUSE / M125 and Klipper's PAUSE/RESUME (SAVE_GCODE_STATE / RESTORE_GCODE_STATE):
//   pause:  stop reading; let the queued commands finish (the print stops at a move boundary);
//           M400 + a short settle dwell; record the position X Y Z E, the feedrate and the G90/G91,
//           M82/M83 and G20/G21 modes; retract, lift Z (clamped to the travel), park in XY;
//           heaters are held at their targets.
//   resume: XY back, then Z,
//   un-retract and prime (`prime_extra_mm`), G92 E back to the recorded
//           E, settle dwell + M400 (the return position is measured here), restore the modes and
//           the feedrate, continue with the next line of the file.
//   cancel: stop reading; every heater off and the machine's queue dropped at once, the motion
//           stopped in a controlled deceleration (JobSink::cancel_motion; while paused nothing of
//           the job is queued: heaters off only); retract, lift, park. Marlin's M524 / Klipper's
//           CANCEL_PRINT.
// A line of the file that fails to parse or that the machine refuses ends the job in `error` with
// the file's name and line; an M25 or M601 in the file pauses the job there; the heaters are
// switched off and the machine is not parked (the failed move may be the reason). The job is not
// tied to any client: a print started by a client runs on after it disconnects. I/O thread only;
// the web API (web/) and the JSON API call start/pause/resume/cancel/status.
#pragma once

#include <cstdint>
#include <cstdio>
#include <deque>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/result.hpp"
#include "daemon/job_files.hpp"
#include "engine/machine.hpp"
#include "gcode/command.hpp"

namespace feedloop::daemon {

enum class JobState {
  kIdle,
  kReady,
  kPrinting,
  kPausing,
  kPaused,
  kResuming,
  kCancelling,
  kComplete,
  kCancelled,
  kError
};
const char* to_string(JobState s);

// What the job needs from the daemon.
class JobSink {
 public:
  virtual ~JobSink() = default;
  enum class Offer { kAccepted, kFull, kRefused };
  // Offers one command to the machine as the job. kAccepted: `done` is called once, on the I/O
  // thread, when it has executed. kFull: no room now, nothing happened (offer it again later).
  // kRefused: nothing happened, `why` says why (e.g. the machine is emergency-stopped).
  virtual Offer offer(const gcode::Command& cmd, std::string_view text,
                      std::function<void(const Status&)> done, std::string* why) = 0;
  virtual engine::MachineStatus machine_status() const = 0;
  virtual int64_t now_ns() const = 0;  // wall clock for elapsed times
  // The narrow heater hook: every heater's target to 0 (today: the HeaterSim targets through the
  // machine's queue, behind the commands already in it).
  virtual void all_heaters_off() = 0;
  // Cancel at once (engine::Machine::flush): every heater's target 0 now, the machine's queue
  // dropped (the job's commands in it complete with an error, which a cancelling job ignores), the
  // motion stopped in a controlled deceleration; the machine then takes the park moves. Default
  // (a sink without it): nothing, the queued commands run first.
  virtual void cancel_motion() {}
  // Whether the job has more lines of its file to hand over (printing, not at the file's end):
  // engine::Machine::set_input_coming. Default: nothing.
  virtual void set_input_coming(bool /*coming*/) {}
  // Whether the machine holds object labels (planner/object_labels.hpp) from an earlier print: a
  // job then starts by resetting them. Default: none.
  virtual bool has_object_labels() const { return false; }
};

struct JobOptions {
  double pause_retract_mm = 1.0;  // filament pulled back on pause and cancel
  double retract_speed_mm_s = 30.0;
  double prime_extra_mm = 0.0;  // pushed on resume beyond the retract
  double lift_mm = 5.0;         // Z raise on pause and cancel (clamped to z_max_mm)
  double z_speed_mm_s = 10.0;
  std::optional<double> park_x_mm, park_y_mm;  // XY park point (none: XY stay)
  double travel_speed_mm_s = 100.0;
  double z_max_mm = 1e9;     // travel limit of Z (logical = machine coordinates)
  // XY travel limits (Cartesian): the resume's way back stays inside them. After a homing
  // through the endstops the carriage stands a little past its limit (the halt's overshoot,
  // e.g. X -0.07 mm for X[0, 250]), where a move would be refused.
  double x_min_mm = -1e9, x_max_mm = 1e9, y_min_mm = -1e9, y_max_mm = 1e9;
  int settle_ms = 1000;      // dwell before a pause/resume position is taken
  int lines_per_pump = 256;  // bounds one pump's work on the I/O thread
  // No line is read while the machine holds more planned motion than this ahead of the motion
  // executing now (Klipper's virtual_sdcard: its lookahead holds about 2 s of moves), so that a
  // pause or cancel stops the print within about that much. 0: as much as the queue takes.
  double read_ahead_s = 2.0;
};

// Marlin's nozzle park (feature/pause.cpp), as G-code lines, for a job's pause and a streaming
// host's M600 (daemon_user_wait.cpp). park_moves: from `at_mm` (X Y Z E), the filament pulled back
// when `retract`, Z raised within its travel, the head to the park point, then M400.
// return_moves: back over the part to `to_mm` in XY (inside the travel), then down, the filament
// pushed by `push_mm`, and E set back to where it was (G92); the caller has set G21 and G90.
std::vector<std::string> park_moves(const JobOptions& o, const double at_mm[4], bool retract);
std::vector<std::string> return_moves(const JobOptions& o, const double to_mm[4], double push_mm);

// A position taken at pause (after the queued moves) and at resume (after the return moves).
struct JobPosition {
  bool valid = false;
  double pos_mm[4] = {0, 0, 0, 0};
  int64_t step_count[4] = {0, 0, 0, 0};
  double encoder_mm[4] = {0, 0, 0, 0};
};

struct JobStatus {
  JobState state = JobState::kIdle;
  std::string file;
  uint64_t size_bytes = 0;
  uint64_t bytes_submitted = 0;    // offset after the last line handed to the machine
  uint64_t lines_submitted = 0;    // file lines (with a command) handed to the machine
  uint64_t lines_read = 0;         // physical lines read
  double progress_bytes = 0.0;     // bytes_submitted / size_bytes
  double progress_time = 0.0;      // print time executed / estimated print time
  double print_time_s = 0.0;       // machine print time executed since the start (no pause moves)
  double estimated_total_s = 0.0;  // from the planner: planned print time / bytes planned * size
  double estimated_remaining_s = 0.0;
  double elapsed_s = 0.0;  // wall time since start
  double paused_s = 0.0;   // wall time spent paused (in total)
  uint64_t pauses = 0;
  // E the file's lines moved, net (retracts subtract), in mm of filament: Klipper's
  // print_stats.filament_used. Counted as lines are handed to the machine (as Klipper counts
  // from gcode_move's position), in the file's E modes (M82/M83, G90/G91, G92 E, G20).
  double filament_used_mm = 0.0;
  std::string message;  // last error or warning
  JobPosition pause_position, resume_position;
};

class PrintJob {
 public:
  PrintJob(JobFiles& files, JobOptions options, JobSink& sink);
  ~PrintJob();
  PrintJob(const PrintJob&) = delete;
  PrintJob& operator=(const PrintJob&) = delete;

  // M23: select a file (not while a job is active).
  Result<JobFileInfo> select(std::string_view name);
  // Klipper's SDCARD_RESET_FILE (Mainsail's "Clear" after a print): back to idle, no file (not
  // while a job is active).
  Status clear();
  // M26 S: the byte the next start reads from (ready state only; the line it falls in is skipped).
  Status set_start_byte(uint64_t byte);
  // Starts `name` (empty: the selected file) from its start byte. Not while a job is active.
  Status start(std::string_view name = {});
  Status pause();
  Status resume();
  Status cancel();
  // Feeds the machine and advances the state machine. I/O thread, never blocks.
  void pump();

  JobStatus status() const;
  JobState state() const { return state_; }
  // Printing, pausing, paused, resuming or cancelling: the job owns the machine.
  bool active() const;
  // Pausing, resuming or cancelling (the job's own move sequences) or printing: the job sends
  // commands now (paused: it does not, and other clients may move the machine).
  bool sending() const { return active() && state_ != JobState::kPaused; }
  const std::string& file() const { return file_; }

 private:
  enum class Phase {
    kNone,
    kPauseWait,
    kPauseSettled,
    kPauseParked,
    kResumeBack,
    kResumeDone,
    kCancelWait,
    kCancelParked
  };
  struct Modes {
    bool relative_xyz = false;
    int e_mode = 0;  // 0: follows G90/G91, 1: M82 absolute, 2: M83 relative
    bool inches = false;
    std::optional<double> feed_units_min;  // last F word
    std::string object;  // the labelled object the file is in (EXCLUDE_OBJECT_START), upper-case
  };
  Status open_file(uint64_t start_byte);
  void close_file();
  // The next physical line of the file into line_; false at the end.
  bool read_line();
  void feed();
  void pump_once();     // pump() without report_input()
  void report_input();  // tells the sink whether lines of the file are still to come
  void track_modes(const gcode::Command& cmd);
  void track_extrusion(const gcode::Command& cmd);
  // Queues one of the job's own lines (pause/resume/cancel sequences).
  void add_sequence(std::string line);
  void send_sequence();
  void on_phase_done();
  void fail(const std::string& message);
  void finish(JobState end);
  JobPosition take_position() const;
  void park_lines(const engine::MachineStatus& at, bool retract);
  std::function<void(const Status&)> completion(bool from_file, int64_t line, std::string text);
  double job_print_time_s(const engine::MachineStatus& s) const;

  JobFiles& files_;
  JobOptions options_;
  JobSink& sink_;
  std::shared_ptr<bool> alive_;  // completions that arrive after destruction do nothing

  JobState state_ = JobState::kIdle;
  Phase phase_ = Phase::kNone;
  std::string file_;
  uint64_t size_ = 0;
  uint64_t start_byte_ = 0;
  std::FILE* fp_ = nullptr;
  uint64_t read_offset_ = 0;  // bytes consumed from the file
  bool eof_ = false;
  std::string read_error_;     // the file could not be read to its end (errno's text)
  bool input_coming_ = false;  // last said to the sink (report_input)
  std::string line_;
  int64_t line_number_ = 0;
  std::optional<gcode::Command> held_;  // parsed, waiting for room
  std::string held_text_;
  int64_t held_line_ = 0;
  uint64_t held_end_offset_ = 0;
  uint64_t bytes_submitted_ = 0, lines_submitted_ = 0;
  size_t in_flight_ = 0;
  std::deque<std::string> sequence_;
  int64_t sequence_number_ = 0;
  Modes modes_;
  Modes saved_modes_;
  JobPosition pause_pos_, resume_pos_;
  bool cancel_after_pause_ = false;
  bool resume_after_pause_ = false;
  bool parked_ = false;
  bool retracted_ = false;      // the pause's park retracted the filament (the hotend was hot)
  bool reset_objects_ = false;  // the start's EXCLUDE_OBJECT_DEFINE RESET=1 is still to be sent
  std::string message_;
  int64_t started_ns_ = 0, ended_ns_ = 0, paused_since_ns_ = 0, paused_total_ns_ = 0;
  uint64_t pauses_ = 0;
  double filament_used_mm_ = 0.0;
  double file_e_mm_ = 0.0;  // the file's logical E after the last line handed over
  double print_time_start_s_ = 0.0;
  double excluded_print_time_s_ = 0.0;  // print time of pause/resume moves
  double exclude_from_s_ = -1.0;
  double planned_at_last_submit_s_ = 0.0;
};

}  // namespace feedloop::daemon
