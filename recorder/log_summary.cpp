// summarize_log / format_summary (see log_summary.hpp).
#include "recorder/log_summary.hpp"

#include <algorithm>
#include <cstdio>

#include "drivers/stepgen/step_run.hpp"  // run_is_valid
#include "recorder/log_reader.hpp"

namespace feedloop::recorder {
namespace {

struct Accumulate {
  LogSummary& s;
  void host(int64_t t) {
    if (!s.has_host_time) s.first_host_ns = s.last_host_ns = t;
    s.first_host_ns = std::min(s.first_host_ns, t);
    s.last_host_ns = std::max(s.last_host_ns, t);
    s.has_host_time = true;
  }
  JointSummary* joint(int j) { return j >= 0 && static_cast<size_t>(j) < s.joints.size() ? &s.joints[static_cast<size_t>(j)] : nullptr; }
  void clock(JointSummary& j, int64_t first, int64_t last) {
    if (!j.has_clock) j.first_clock = first, j.last_clock = last;
    j.first_clock = std::min(j.first_clock, first);
    j.last_clock = std::max(j.last_clock, last);
    j.has_clock = true;
  }
  void operator()(const GcodeLineRecord& r) {
    ++s.gcode_lines;
    if (r.original_length > r.text.size()) ++s.truncated_lines;
    host(r.time_ns);
  }
  void operator()(const MoveRecord& r) {
    ++s.moves;
    if (!s.has_print_time || r.start_time_s < s.first_print_s) s.first_move_start_mm = r.start_mm;
    if (!s.has_print_time) s.first_print_s = r.start_time_s, s.last_print_s = r.start_time_s;
    s.first_print_s = std::min(s.first_print_s, r.start_time_s);
    s.last_print_s = std::max(s.last_print_s, r.start_time_s + r.duration_s);
    s.has_print_time = true;
  }
  void operator()(const SegmentRecord& r) {
    if (JointSummary* j = joint(r.joint)) ++j->segments;
  }
  void operator()(const StepRunRecord& r) {
    JointSummary* j = joint(r.joint);
    if (!j) return;
    ++j->step_runs;
    j->steps += r.run.count;
    j->net_steps += r.run.direction < 0 ? -static_cast<int64_t>(r.run.count) : static_cast<int64_t>(r.run.count);
    if (r.run.count == 0) return;
    // A run with an interval below 1 tick or clocks beyond 2^63 has no step clocks to speak of.
    if (!stepgen::run_is_valid(r.start_clock, r.run)) {
      ++j->invalid_runs;
      return;
    }
    clock(*j, stepgen::run_step_clock(r.start_clock, r.run, 1),
          stepgen::run_end_clock(r.start_clock, r.run));
  }
  void operator()(const EncoderRecord& r) {
    JointSummary* j = joint(r.joint);
    if (!j) return;
    ++j->encoder_samples;
    clock(*j, r.clock, r.clock);
  }
  void operator()(const OriginRecord&) {}
  void operator()(const LoopReportRecord& r) {
    JointSummary* j = joint(r.joint);
    if (!j) return;
    ++j->loop_reports;
    if (r.state == 1) {  // running
      const double e_mm = static_cast<double>(r.e_nm < 0 ? -r.e_nm : r.e_nm) * 1e-6;
      j->loop_max_abs_e_mm = std::max(j->loop_max_abs_e_mm, e_mm);
      j->loop_sum_abs_e_mm += e_mm;
      ++j->loop_running_reports;
    }
    j->loop_max_tick_cost = std::max(j->loop_max_tick_cost, r.tick_cost);
    j->loop_slips = std::max(j->loop_slips, r.slips);
    j->loop_deadline_misses = std::max(j->loop_deadline_misses, r.deadline_misses);
  }
  void operator()(const EventRecord& r) {
    if (static_cast<int>(r.kind) < kEventKinds) ++s.events[static_cast<size_t>(r.kind)];
    host(r.time_ns);
  }
  void operator()(const DropRecord& r) {
    auto& d = s.dropped[static_cast<size_t>(r.stream)];
    d = std::max(d, r.dropped_total);
  }
  void operator()(const TimeSyncRecord& r) { host(r.host_ns); }
};

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

}  // namespace

Result<LogSummary> summarize_log(const std::string& path) {
  auto reader = LogReader::open(path);
  if (!reader) return reader.error();
  LogSummary s;
  s.header = reader->header();
  s.path = path;
  s.file_size_bytes = reader->file_size();
  s.joints.resize(s.header.joints.size());
  Accumulate acc{s};
  while (const DecodedRecord* d = reader->next()) {
    ++s.records;
    const auto t = static_cast<size_t>(record_type(d->record));
    ++s.count_by_type[t];
    s.bytes_by_type[t] += d->size;
    std::visit(acc, d->record);
  }
  s.blocks = reader->blocks();
  s.damage = reader->error();
  return s;
}

std::string format_summary(const LogSummary& s) {
  std::string o;
  auto line = [&o](const std::string& l) { o += l + "\n"; };
  line("log:        " + s.path);
  line("print:      " + s.header.print_name + " (part " + std::to_string(s.header.part) + ", format v" +
       std::to_string(s.header.version) + ")");
  line("file size:  " + std::to_string(s.file_size_bytes) + " bytes, " + std::to_string(s.blocks) + " blocks, " +
       std::to_string(s.records) + " records");
  line("duration:   " + fmt("%.3f", s.host_duration_s()) + " s host time, " + fmt("%.3f", s.print_duration_s()) +
       " s print time (moves)");
  line("g-code:     " + std::to_string(s.gcode_lines) + " lines" +
       (s.truncated_lines ? " (" + std::to_string(s.truncated_lines) + " cut to the text limit)" : std::string()));
  line("moves:      " + std::to_string(s.moves) +
       (s.has_print_time
            ? ", the first from X " + fmt("%.4f", s.first_move_start_mm[0]) + " Y " +
                  fmt("%.4f", s.first_move_start_mm[1]) + " Z " +
                  fmt("%.4f", s.first_move_start_mm[2]) +
                  " mm (the machine's frame; `feedloop ident fit --start-mm` of an exported trace)"
            : std::string()));
  for (size_t j = 0; j < s.joints.size(); ++j) {
    const JointInfo& ji = s.header.joints[j];
    const JointSummary& js = s.joints[j];
    std::string l = "joint " + ji.name + ":" + std::string(ji.name.size() < 5 ? 5 - ji.name.size() : 0, ' ') +
                    std::to_string(js.steps) + " steps (net " + std::to_string(js.net_steps) + ") in " +
                    std::to_string(js.step_runs) + " runs, " + std::to_string(js.segments) + " segments, " +
                    std::to_string(js.encoder_samples) + " encoder samples";
    if (js.invalid_runs)
      l += ", " + std::to_string(js.invalid_runs) +
           " runs breaking the step law (an interval below 1 tick or clocks beyond 2^63)";
    if (js.has_clock && ji.clock_hz > 0)
      l += ", MCU time " + fmt("%.3f", static_cast<double>(js.first_clock) / static_cast<double>(ji.clock_hz)) + ".." +
           fmt("%.3f", static_cast<double>(js.last_clock) / static_cast<double>(ji.clock_hz)) + " s";
    line(l);
    if (js.loop_reports > 0) {
      const double mean_e_mm =
          js.loop_running_reports > 0 ? js.loop_sum_abs_e_mm / static_cast<double>(js.loop_running_reports) : 0.0;
      line("  device loop: " + std::to_string(js.loop_reports) + " reports, |e| mean " + fmt("%.4f", mean_e_mm) +
           " mm, max " + fmt("%.4f", js.loop_max_abs_e_mm) + " mm (while running), max tick cost " +
           std::to_string(js.loop_max_tick_cost) + " (ns on the virtual MCU), " + std::to_string(js.loop_slips) +
           " slips, " + std::to_string(js.loop_deadline_misses) + " deadline misses");
    }
  }
  std::string ev;
  for (int k = 0; k < kEventKinds; ++k)
    if (s.events[static_cast<size_t>(k)])
      ev += std::string(ev.empty() ? "" : ", ") + event_kind_name(static_cast<EventKind>(k)) + " " +
            std::to_string(s.events[static_cast<size_t>(k)]);
  line("events:     " + (ev.empty() ? std::string("none") : ev));
  std::string dr;
  uint64_t total_dropped = 0;
  for (int k = 0; k < kStreams; ++k) {
    total_dropped += s.dropped[static_cast<size_t>(k)];
    dr += std::string(k ? ", " : "") + stream_name(static_cast<Stream>(k)) + " " + std::to_string(s.dropped[static_cast<size_t>(k)]);
  }
  line("dropped:    " + dr + (total_dropped ? "  (rings were full: the log is incomplete)" : ""));
  line("bytes per record:");
  for (int t = 1; t < kRecordTypes; ++t) {
    const uint64_t n = s.count_by_type[static_cast<size_t>(t)];
    if (!n) continue;
    const double b = static_cast<double>(s.bytes_by_type[static_cast<size_t>(t)]) / static_cast<double>(n);
    char buf[96];
    std::snprintf(buf, sizeof buf, "  %-11s %10llu records  %6.2f bytes each", record_type_name(static_cast<RecordType>(t)),
                  static_cast<unsigned long long>(n), b);
    line(buf);
  }
  if (s.damage) line("DAMAGED:    " + s.damage->message + " (everything before it was read)");
  return o;
}

}  // namespace feedloop::recorder
