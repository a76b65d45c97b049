// Names of the enums in records.hpp (for `feedloop log info` and messages).
#include "recorder/records.hpp"

#include <iterator>  // std::size

namespace feedloop::recorder {

const char* stream_name(Stream s) {
  switch (s) {
    case Stream::io: return "io";
    case Stream::planner: return "planner";
    case Stream::servo: return "servo";
  }
  return "?";
}

const char* gcode_source_name(GcodeSource s) {
  switch (s) {
    case GcodeSource::file: return "file";
    case GcodeSource::socket: return "socket";
    case GcodeSource::pty: return "pty";
    case GcodeSource::api: return "api";
    case GcodeSource::other: return "other";
  }
  return "?";
}

const char* event_kind_name(EventKind k) {
  switch (k) {
    case EventKind::info: return "info";
    case EventKind::warning: return "warning";
    case EventKind::error: return "error";
    case EventKind::lost_steps: return "lost_steps";
    case EventKind::deadline_miss: return "deadline_miss";
    case EventKind::time_anchor: return "time_anchor";
    case EventKind::print_start: return "print_start";
    case EventKind::print_end: return "print_end";
  }
  return "?";
}

const char* record_type_name(RecordType t) {
  switch (t) {
    case RecordType::gcode_line: return "gcode_line";
    case RecordType::move: return "move";
    case RecordType::segment: return "segment";
    case RecordType::step_run: return "step_run";
    case RecordType::encoder: return "encoder";
    case RecordType::origin: return "origin";
    case RecordType::event: return "event";
    case RecordType::drops: return "drops";
    case RecordType::time_sync: return "time_sync";
    case RecordType::loop_report: return "loop_report";
  }
  return "unknown";
}

RecordType record_type(const Record& r) {
  static constexpr RecordType kByIndex[] = {RecordType::gcode_line, RecordType::move,   RecordType::segment,
                                            RecordType::step_run,   RecordType::encoder, RecordType::origin,
                                            RecordType::event,      RecordType::drops,   RecordType::time_sync,
                                            RecordType::loop_report};
  static_assert(std::size(kByIndex) == std::variant_size_v<Record>);
  return kByIndex[r.index()];
}

}  // namespace feedloop::recorder
