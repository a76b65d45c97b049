// What `feedloop log info` prints: counts per record type and joint, time spans, drops, events,
// encoded bytes per record, and the damage found (if any).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/result.hpp"
#include "recorder/records.hpp"

namespace feedloop::recorder {

struct JointSummary {
  uint64_t step_runs = 0;
  uint64_t steps = 0;         // steps sent, both directions
  int64_t net_steps = 0;      // + minus -
  uint64_t segments = 0;
  uint64_t encoder_samples = 0;
  uint64_t invalid_runs = 0;  // runs that break the step law (damage): not in the clock span
  // Device loop reports (loop_report records): |e| while running, the largest tick cost.
  uint64_t loop_reports = 0, loop_running_reports = 0;
  double loop_max_abs_e_mm = 0.0, loop_sum_abs_e_mm = 0.0;
  uint32_t loop_max_tick_cost = 0;
  uint64_t loop_slips = 0, loop_deadline_misses = 0;
  int64_t first_clock = 0, last_clock = 0;  // steps and encoder samples
  bool has_clock = false;
};

struct LogSummary {
  LogHeader header;
  std::string path;
  uint64_t file_size_bytes = 0;
  uint64_t blocks = 0;
  uint64_t records = 0;
  std::array<uint64_t, kRecordTypes> count_by_type{};  // index: RecordType code
  std::array<uint64_t, kRecordTypes> bytes_by_type{};  // encoded bytes (tag included)
  uint64_t gcode_lines = 0, truncated_lines = 0, moves = 0;
  std::vector<JointSummary> joints;                    // header order
  std::array<uint64_t, kEventKinds> events{};
  std::array<uint64_t, kStreams> dropped{};
  // Host time span (G-code lines, events, time syncs) and print time span (moves).
  int64_t first_host_ns = 0, last_host_ns = 0;
  bool has_host_time = false;
  double first_print_s = 0.0, last_print_s = 0.0;
  bool has_print_time = false;
  // Where the earliest planned move starts (X Y Z E, the machine's frame): a recording's step
  // positions count from the print's start, and `feedloop ident fit --start-mm` takes this.
  std::array<double, 4> first_move_start_mm{};
  std::optional<Error> damage;                          // where reading stopped early

  double host_duration_s() const { return has_host_time ? 1e-9 * static_cast<double>(last_host_ns - first_host_ns) : 0.0; }
  double print_duration_s() const { return has_print_time ? last_print_s - first_print_s : 0.0; }
};

// Reads the whole log. Error only if the file cannot be opened or has no valid header.
Result<LogSummary> summarize_log(const std::string& path);

// Human-readable text for `feedloop log info`.
std::string format_summary(const LogSummary& s);

}  // namespace feedloop::recorder
