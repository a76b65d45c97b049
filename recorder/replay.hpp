// Recording a simulated print and replaying a recorded one (`feedloop replay`, docs/recorder.md).
//
// Both run the daemon's motion stack (engine::make_motion_stack: interpreter, lookahead, step
// pipeline, MCU bridge with the mock MCUs driving the plant simulator) in virtual time from one
// thread, with the flight recorder on: commands are executed on the planner side and the servo
// cycle runs every period in between. Nothing depends on thread scheduling, so the same G-code and
// config give the same log, bit for bit (the step runs, moves, encoder samples).
//
// A replay reads the G-code lines of a recording (its parts in order) and its config (from the log
// header, or --config), records the re-run into its own log, and compares:
//  - the planned moves (the first difference, if any, explains a step difference: the lookahead
//    was released at other points, e.g. because the recorded input arrived with other timing);
//  - the time anchors (offset with host time = print time + offset, one per motion start);
//  - the commanded step streams, step by step (recorder/step_stream.hpp): bit-identical when the
//    config is the same;
//  - the encoder data: recorded minus simulated per joint (RMS and max), the model's residual on
//    that print.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "config/machine_config.hpp"
#include "core/result.hpp"
#include "recorder/engine_recording.hpp"
#include "recorder/records.hpp"

namespace feedloop::recorder {

struct VirtualPrintOptions {
  double settle_s = 0.05;        // keep running this long after the motion ended
  double timeout_s = 3600.0;     // of virtual time
  double poll_period_s = 0.02;   // the recorder is drained every this much virtual time
  EngineRecordingOptions recording;
  size_t servo_ring_bytes = 8 << 20;
};

struct VirtualPrintResult {
  std::vector<std::string> logs;  // the parts of the print, in order
  uint64_t commands = 0;          // lines executed
  uint64_t rejected = 0;          // lines that failed to parse or execute
  std::string first_error;        // "line N: message" of the first rejected line
  double virtual_s = 0.0;         // virtual time from the first servo cycle to the end
  uint64_t anchors = 0;           // motion starts from rest
  uint64_t encoder_samples = 0;
  RecorderStats recorder;
};

// Runs `lines` through the motion stack of `cfg` (which must use mock MCUs) in virtual time and
// records the print into `directory` (created if needed) as `print_name`. `config_yaml` goes into
// the log header (what a replay re-loads). The recorder settings of cfg are ignored but for
// max_file_size_mb and keep_files.
Result<VirtualPrintResult> record_virtual_print(const config::MachineConfig& cfg, const std::string& config_yaml,
                                                const std::vector<std::string>& lines,
                                                const std::string& directory, const std::string& print_name,
                                                const VirtualPrintOptions& options = {});

// The parts of the print whose last part is `last_part` ("<stamp>_<name>_pNNN.flrec"), in order.
std::vector<std::string> print_log_parts(const std::string& last_part);

// Everything a replay needs from a recording, read from its parts in order. A missing, corrupt or
// truncated log is an Error naming the file and the byte offset of the damage.
struct RecordedPrint {
  LogHeader header;  // of the first part
  std::vector<GcodeLineRecord> gcode;
  std::vector<MoveRecord> moves;
  std::vector<double> anchors_s;  // time_anchor offsets, in order
  std::vector<std::vector<EncoderRecord>> encoders;  // [joint]
  uint64_t records = 0;
};
Result<RecordedPrint> read_recorded_print(const std::vector<std::string>& logs);

// Recorded minus simulated encoder position of one joint. The simulated samples are interpolated
// linearly at the recorded sample clocks; both clocks are taken relative to the joint's first
// step (so a recording on another MCU clock still lines up when the step streams do).
struct JointResidual {
  std::string joint;
  uint64_t samples = 0;  // recorded samples inside the simulated data's time span
  double rms_um = 0.0;
  double max_abs_um = 0.0;
  double mean_um = 0.0;
};

struct ReplayOptions {
  std::string config_path;  // empty: the config in the log header
  std::string out_dir;      // where the replay's own log goes; empty: a fresh temporary directory
  bool keep_log = false;    // keep the replay log (always kept when out_dir is given)
  VirtualPrintOptions run;
};

struct ReplayReport {
  std::vector<std::string> recorded_logs;
  std::vector<std::string> replay_logs;  // empty unless kept
  std::string config_source;             // "log header" or the --config path
  uint64_t gcode_lines = 0;
  uint64_t rejected = 0;
  std::string first_error;
  uint64_t recorded_moves = 0, replayed_moves = 0;
  std::optional<std::string> move_mismatch;    // the first differing move, described
  std::optional<std::string> anchor_mismatch;  // the first differing time anchor
  uint64_t recorded_anchors = 0, replayed_anchors = 0;
  uint64_t steps_compared = 0;                 // steps per stream (sum over joints, recorded)
  std::optional<std::string> step_mismatch;    // nullopt: bit-identical
  std::vector<JointResidual> residuals;        // joints with encoder data in both
  bool steps_identical() const { return !step_mismatch.has_value(); }
  std::string to_text() const;  // the report `feedloop replay` prints
};

Result<ReplayReport> replay_print(const std::vector<std::string>& logs, const ReplayOptions& options = {});

// The residual computation on its own (tests): `recorded` and `simulated` samples of one joint,
// first steps of that joint in each log (clock of the first step; 0 if none).
JointResidual encoder_residual(const std::string& joint, const std::vector<EncoderRecord>& recorded,
                               int64_t recorded_first_step, const std::vector<EncoderRecord>& simulated,
                               int64_t simulated_first_step, double resolution_mm);

}  // namespace feedloop::recorder
