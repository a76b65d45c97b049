// The records of a flight-recorder log, as the reader returns them and (for the fixed-size ones)
// as the real-time side copies them into its ring. Times: `*_ns` is host time on the engine's
// Clock (monotonic in the daemon, virtual in batch/replay); `*_s` of moves and segments is print
// time; `clock` of step runs and encoder samples is the joint's MCU clock in ticks
// (LogHeader::joints[j].clock_hz). Format and encoding: docs/recorder.md.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <variant>
#include <vector>

#include "core/joint_segment.hpp"
#include "drivers/stepgen/step_run.hpp"

namespace feedloop::recorder {

inline constexpr uint16_t kFormatVersion = 2;  // 2: loop_report records (1 has none)
inline constexpr int kMaxJoints = 8;  // joint index lives in 3 bits of a record tag

// The three producer threads; each owns one ring (RecordWriter).
enum class Stream : uint8_t { io = 0, planner = 1, servo = 2 };
inline constexpr int kStreams = 3;
const char* stream_name(Stream s);

enum class GcodeSource : uint8_t { file = 0, socket = 1, pty = 2, api = 3, other = 4 };
const char* gcode_source_name(GcodeSource s);

enum class EventKind : uint8_t {
  info = 0,
  warning = 1,
  error = 2,
  lost_steps = 3,     // value: steps (or mm) lost, joint set
  deadline_miss = 4,  // value: lateness in seconds
  time_anchor = 5,    // value: offset_s with mcu_time = print_time + offset (engine re-anchors)
  print_start = 6,
  print_end = 7,
};
inline constexpr int kEventKinds = 8;
const char* event_kind_name(EventKind k);

// Per-joint facts in the file header.
struct JointInfo {
  std::string name;                    // x, y, z, e, or A, B, C
  double steps_per_mm = 0.0;
  double encoder_resolution_mm = 0.0;  // 0: no encoder on this joint
  int64_t clock_hz = 0;                // MCU clock of the step runs / encoder samples
  bool operator==(const JointInfo&) const = default;
};

struct LogHeader {
  uint16_t version = kFormatVersion;
  std::string print_name;
  uint32_t part = 0;           // 0 for the first file of a print, +1 per rotation
  int64_t start_unix_ns = 0;   // wall clock when the file was opened
  int64_t start_host_ns = 0;   // host (engine Clock) time when the file was opened
  std::vector<JointInfo> joints;
  std::string config_yaml;     // the config text the machine ran with
};

// ---- records --------------------------------------------------------------------------------

struct GcodeLineRecord {
  int64_t time_ns = 0;           // arrival time
  GcodeSource source = GcodeSource::other;
  uint32_t original_length = 0;  // > text.size() when the line was truncated on recording
  std::string text;
  bool operator==(const GcodeLineRecord&) const = default;
};

// The fields of planner::PlannedMove that matter for analysis (POD: also the ring payload).
struct MoveRecord {
  uint64_t index = 0;
  int32_t line = 0;
  double start_time_s = 0.0;
  double duration_s = 0.0;
  std::array<double, 4> start_mm{};  // X Y Z E
  std::array<double, 4> end_mm{};
  double v_entry_mm_s = 0.0;
  double v_cruise_mm_s = 0.0;
  double v_exit_mm_s = 0.0;
  double accel_mm_s2 = 0.0;
  bool operator==(const MoveRecord&) const = default;
};

struct SegmentRecord {
  int32_t joint = 0;
  JointSegment segment;
};

// One compressed step run (bit-exact: the commanded step stream is these, in order per joint).
struct StepRunRecord {
  int32_t joint = 0;
  int64_t start_clock = 0;  // the run's reference P (clock of the step before its first)
  stepgen::StepRun run;
};

struct EncoderRecord {
  int32_t joint = 0;
  int64_t clock = 0;   // MCU timestamp of the sample
  int64_t counts = 0;  // position in encoder counts
  bool operator==(const EncoderRecord&) const = default;
};

// From `clock` on, the joint's step counter is `position_steps` (start of a stream, homing, G92).
struct OriginRecord {
  int32_t joint = 0;
  int64_t clock = 0;
  int64_t position_steps = 0;
  bool operator==(const OriginRecord&) const = default;
};

struct EventRecord {
  EventKind kind = EventKind::info;
  int64_t time_ns = 0;
  int32_t joint = -1;  // -1: not about one joint
  double value = 0.0;
  std::string text;
  bool operator==(const EventRecord&) const = default;
};

// One LOOP_REPORT of a joint's device loop (control.loop: device; docs/protocol.md section 11):
// its state, e = r - y, the encoder y and the PI's correction u at the report's tick, the largest
// cost of one tick in the report window, and the loop's counters. Positions in nm (the MCU's
// frame, as on the wire).
struct LoopReportRecord {
  int32_t joint = 0;
  int64_t clock = 0;         // the tick, on the joint's MCU clock
  uint8_t state = 0;         // 0 idle, 1 running, 2 stopping, 3 stopped
  int64_t e_nm = 0;
  int64_t y_nm = 0;
  int64_t correction_nm = 0;
  uint32_t tick_cost = 0;    // ns on the virtual MCU, cycles on a firmware
  uint64_t ticks = 0, deadline_misses = 0, encoder_rejects = 0, slips = 0;
  bool operator==(const LoopReportRecord&) const = default;
};

// Written by the recorder thread when a ring was full: records dropped on that stream since the
// file was opened (a running total: the last DropRecord of a stream in a file is its count).
struct DropRecord {
  Stream stream = Stream::io;
  uint64_t dropped_total = 0;
  bool operator==(const DropRecord&) const = default;
};

// Written by the recorder thread at the start of every block: host time <-> wall clock.
struct TimeSyncRecord {
  int64_t host_ns = 0;
  int64_t unix_ns = 0;
  bool operator==(const TimeSyncRecord&) const = default;
};

using Record = std::variant<GcodeLineRecord, MoveRecord, SegmentRecord, StepRunRecord, EncoderRecord,
                            OriginRecord, EventRecord, DropRecord, TimeSyncRecord, LoopReportRecord>;

// Record type codes on disk (low 4 bits of the tag byte).
enum class RecordType : uint8_t {
  gcode_line = 1,
  move = 2,
  segment = 3,
  step_run = 4,
  encoder = 5,
  origin = 6,
  event = 7,
  drops = 8,
  time_sync = 9,
  loop_report = 10,  // format version 2
};
inline constexpr int kRecordTypes = 11;  // codes 1..10 (0 unused)
const char* record_type_name(RecordType t);
RecordType record_type(const Record& r);

}  // namespace feedloop::recorder
