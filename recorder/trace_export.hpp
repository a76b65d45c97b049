// Flight-recorder log(s) -> trace CSV v1 (DESIGN.md, "Contracts"): for every joint that has step
// runs or encoder samples, <a>_cmd_mm = steps sent x mm/step, reconstructed exactly from the step
// runs at each sample time, and <a>_meas_mm = encoder counts x resolution (linear interpolation
// between samples; held before the first and after the last). A joint without encoder samples
// gets meas = cmd, said in a '#' line. Rows every 1/rate_hz from the first to the last data time.
#pragma once

#include <string>
#include <vector>

#include "core/result.hpp"

namespace feedloop::recorder {

// The rates an export may sample at, and the memory its columns may take (a 1 kHz export of four
// joints holds 72 bytes a row: 15 hours in 4 GiB).
inline constexpr double kMinExportRateHz = 1.0;
inline constexpr double kMaxExportRateHz = 100e3;
inline constexpr double kMaxExportBytes = 4.0 * 1024.0 * 1024.0 * 1024.0;

struct ExportOptions {
  double rate_hz = 1000.0;  // kMinExportRateHz .. kMaxExportRateHz
};

struct TraceColumns {
  double t0_s = 0.0;                       // MCU time of the first row (time_s is relative to it)
  double rate_hz = 0.0;
  std::vector<double> time_s;
  std::vector<std::string> joints;         // names of the exported joints
  std::vector<std::vector<double>> cmd_mm, meas_mm;  // [joint][row]
  // [joint]: time_s of its first and last encoder sample (NaN without any); outside them the
  // reading is held, not measured.
  std::vector<std::pair<double, double>> meas_span_s;
  std::vector<std::string> comments;       // '#' lines (without the '# ')
  // Servo-stream records the recorder dropped (its ring was full), summed over the logs. Step runs
  // or encoder samples may be missing: cmd_mm can be off for good after the first. A warning
  // comment says so; `feedloop calibrate` refuses such a trace.
  uint64_t servo_records_dropped = 0;
};

// Reads the logs in order (parts of one print, or one file). Error when a file cannot be read,
// when the logs have no step or encoder data, or the rate is not positive. A damaged tail is a
// warning in `comments`, the data before it is exported.
Result<TraceColumns> build_trace(const std::vector<std::string>& logs, const ExportOptions& options);

// Writes trace CSV v1.
Status write_trace_csv(const TraceColumns& trace, const std::string& csv_path);

}  // namespace feedloop::recorder
