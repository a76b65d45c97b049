// Trace CSV v1 (DESIGN.md contract): read and write measured or simulated axis data.
//
//   # sample_rate_hz=1000            optional metadata lines starting with '#'
//   time_s,x_cmd_mm,x_meas_mm[,y_cmd_mm,y_meas_mm...]   header; extra columns are ignored
//   0.000,0.0,0.0                    one row per sample, time increasing
//
// Errors (a malformed number, a missing column, time not increasing) are values located at the
// file, line and column where they occur.
#pragma once

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

  size_t samples() const { return time_s.size(); }
  // Mean sample period from the time column (0 with fewer than two samples).
  double period_s() const;
  // The axis with that name, or nullptr.
  const AxisTrace* axis(const std::string& name) const;
};

// Parses trace CSV v1 text; `source` names it in error locations.
Result<Trace> parse_trace_csv(const std::string& text, const std::string& source = "<trace>");
Result<Trace> read_trace_csv(const std::string& path);

// Writes trace CSV v1 (metadata lines first). Errors: axes of different lengths, I/O failure.
std::string format_trace_csv(const Trace& trace);
Status write_trace_csv(const std::string& path, const Trace& trace);

}  // namespace feedloop::ident
