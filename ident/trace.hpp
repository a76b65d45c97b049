// Trace CSV v1 (DESIGN.md contract): read and write measured or simulated axis data.
//
//   # sample_rate_hz=1000            optional metadata lines starting with '#'
//   time_s,x_cmd_mm,x_meas_mm[,y_cmd_mm,y_meas_mm...]   header; extra columns are ignored
//   0.000,0.0,0.0                    one row per sample, time increasing
//
// Errors (a malformed number, a missing column, time not increasing) are values located at the
// file, line and column where they occur. evenly_sampled() puts a trace on the even grid that the
// identification needs.
#pragma once

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "core/result.hpp"

namespace feedloop::ident {

struct AxisTrace {
  std::string name;               // x, y, z, e, A, B, C ...
  std::vector<double> cmd_mm;     // commanded motor position (steps sent x mm per step)
  std::vector<double> meas_mm;    // encoder-measured carriage position
};

struct Trace {
  std::vector<std::pair<std::string, std::string>> metadata;  // "# key=value" lines, in order
  std::vector<double> time_s;
  std::vector<AxisTrace> axes;
  std::vector<int>
      row_line;  // the file line of each row (parsed traces; empty when built in memory)

  size_t samples() const { return time_s.size(); }
  // Mean sample period from the time column (0 with fewer than two samples).
  double period_s() const;
  // The axis with that name, or nullptr.
  const AxisTrace* axis(const std::string& name) const;
};

// Parses trace CSV v1 text; `source` names it in error locations.
Result<Trace> parse_trace_csv(const std::string& text, const std::string& source = "<trace>");
// Files up to kMaxTraceFileBytes (a calibration trace of 100 s at 1 kHz is ~3 MB).
inline constexpr size_t kMaxTraceFileBytes = size_t{256} << 20;
Result<Trace> read_trace_csv(const std::string& path);

// The trace on an even time grid, as the identification and the FRF need it (the contract asks
// only that time increases). Steps within 1 % of the median step: the trace as it is. Uneven
// steps up to 2.5 medians (a jittered clock, one lost row): every column linearly interpolated
// onto the median step from the first time, and *note (when given) says so. A longer step means
// rows are missing: an error located at the row after the gap (interpolating across it would be
// fitted as motion). `source` names the trace in the error.
Result<Trace> evenly_sampled(const Trace& trace, const std::string& source,
                             std::string* note = nullptr);

// Writes trace CSV v1 (metadata lines first). Errors: axes of different lengths, I/O failure.
std::string format_trace_csv(const Trace& trace);
Status write_trace_csv(const std::string& path, const Trace& trace);

}  // namespace feedloop::ident
