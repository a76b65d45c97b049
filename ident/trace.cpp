// Trace CSV v1 reader and writer (see trace.hpp).
#include "ident/trace.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "core/bounded_file.hpp"

namespace feedloop::ident {
namespace {

std::vector<std::string> split_commas(const std::string& line, std::vector<int>* columns) {
  std::vector<std::string> out;
  size_t start = 0;
  while (true) {
    const size_t comma = line.find(',', start);
    std::string cell = line.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    // Trim spaces and a trailing carriage return.
    size_t b = 0, e = cell.size();
    while (b < e && (cell[b] == ' ' || cell[b] == '\t')) ++b;
    while (e > b && (cell[e - 1] == ' ' || cell[e - 1] == '\t' || cell[e - 1] == '\r')) --e;
    out.push_back(cell.substr(b, e - b));
    if (columns != nullptr) columns->push_back(static_cast<int>(start + b) + 1);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return out;
}

Error located(const std::string& msg, const std::string& source, int line, int column) {
  return Error{msg, SourceLocation{source, line, column}};
}

bool parse_double(const std::string& s, double* v) {
  if (s.empty()) return false;
  errno = 0;
  char* end = nullptr;
  *v = std::strtod(s.c_str(), &end);
  return errno == 0 && end == s.c_str() + s.size() && std::isfinite(*v);
}

}  // namespace

double Trace::period_s() const {
  if (time_s.size() < 2) return 0.0;
  return (time_s.back() - time_s.front()) / static_cast<double>(time_s.size() - 1);
}

const AxisTrace* Trace::axis(const std::string& name) const {
  for (const auto& a : axes)
    if (a.name == name) return &a;
  return nullptr;
}

Result<Trace> parse_trace_csv(const std::string& text, const std::string& source) {
  Trace trace;
  std::istringstream in(text);
  std::string line;
  int line_no = 0;
  bool have_header = false;
  // Column index of cmd and meas per axis.
  std::vector<std::pair<size_t, size_t>> cols;
  size_t ncols = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (!have_header) {
      if (line.empty()) continue;
      if (line[0] == '#') {
        std::string body = line.substr(1);
        const size_t b = body.find_first_not_of(" \t");
        body = b == std::string::npos ? std::string() : body.substr(b);
        const size_t eq = body.find('=');
        if (eq != std::string::npos)
          trace.metadata.emplace_back(body.substr(0, eq), body.substr(eq + 1));
        else
          trace.metadata.emplace_back(body, "");
        continue;
      }
      std::vector<int> colpos;
      const auto names = split_commas(line, &colpos);
      if (names[0] != "time_s")
        return located("trace header must start with 'time_s', found '" + names[0] + "'", source, line_no, colpos[0]);
      ncols = names.size();
      for (size_t i = 1; i < names.size(); ++i) {
        const std::string& n = names[i];
        const std::string suffix = "_cmd_mm";
        if (n.size() > suffix.size() && n.compare(n.size() - suffix.size(), suffix.size(), suffix) == 0) {
          const std::string axis = n.substr(0, n.size() - suffix.size());
          const std::string meas = axis + "_meas_mm";
          size_t j = 0;
          for (j = 1; j < names.size(); ++j)
            if (names[j] == meas) break;
          if (j == names.size())
            return located("column '" + n + "' has no matching '" + meas + "' column", source, line_no, colpos[i]);
          trace.axes.push_back(AxisTrace{axis, {}, {}});
          cols.emplace_back(i, j);
        }
      }
      if (trace.axes.empty())
        return located("trace header names no '<axis>_cmd_mm,<axis>_meas_mm' columns", source, line_no, 1);
      have_header = true;
      continue;
    }
    if (line.empty()) continue;
    if (line[0] == '#') continue;  // comments between rows are tolerated
    std::vector<int> colpos;
    const auto cells = split_commas(line, &colpos);
    if (cells.size() < ncols)
      return located("row has " + std::to_string(cells.size()) + " columns, header has " + std::to_string(ncols),
                     source, line_no, static_cast<int>(line.size()) + 1);
    double t = 0.0;
    if (!parse_double(cells[0], &t))
      return located("not a number: '" + cells[0] + "'", source, line_no, colpos[0]);
    if (!trace.time_s.empty() && !(t > trace.time_s.back()))
      return located("time_s must increase (" + cells[0] + " after " + std::to_string(trace.time_s.back()) + ")",
                     source, line_no, colpos[0]);
    trace.time_s.push_back(t);
    trace.row_line.push_back(line_no);
    for (size_t a = 0; a < cols.size(); ++a) {
      double c = 0.0, m = 0.0;
      if (!parse_double(cells[cols[a].first], &c))
        return located("not a number: '" + cells[cols[a].first] + "'", source, line_no, colpos[cols[a].first]);
      if (!parse_double(cells[cols[a].second], &m))
        return located("not a number: '" + cells[cols[a].second] + "'", source, line_no, colpos[cols[a].second]);
      trace.axes[a].cmd_mm.push_back(c);
      trace.axes[a].meas_mm.push_back(m);
    }
  }
  if (!have_header) return located("trace has no header row", source, line_no, 0);
  if (trace.time_s.size() < 2) return located("trace has fewer than two samples", source, line_no, 0);
  return trace;
}

Result<Trace> read_trace_csv(const std::string& path) {
  // A path that never ends (/dev/zero) or a file far beyond an identification's trace is refused
  // instead of filling memory.
  const BoundedFile f = read_file_bounded(path, kMaxTraceFileBytes);
  switch (f.status) {
    case BoundedFile::Status::kOk:
      return parse_trace_csv(f.text, path);
    case BoundedFile::Status::kCannotOpen:
      return Error{"cannot open trace file", SourceLocation{path, 0, 0}};
    case BoundedFile::Status::kTooLarge:
      return Error{"trace file is larger than " + std::to_string(kMaxTraceFileBytes >> 20) +
                       " MiB (about 1.5 hours of one axis at 1 kHz): export or cut a shorter part",
                   SourceLocation{path, 0, 0}};
    case BoundedFile::Status::kReadError:
      break;
  }
  return Error{"cannot read trace file", SourceLocation{path, 0, 0}};
}

Result<Trace> evenly_sampled(const Trace& trace, const std::string& source, std::string* note) {
  if (note != nullptr) note->clear();
  const size_t n = trace.time_s.size();
  if (n < 3) return trace;
  std::vector<double> steps(n - 1);
  for (size_t i = 0; i + 1 < n; ++i) steps[i] = trace.time_s[i + 1] - trace.time_s[i];
  std::vector<double> sorted = steps;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(sorted.size() / 2),
                   sorted.end());
  const double median = sorted[sorted.size() / 2];
  const auto [lo, hi] = std::minmax_element(steps.begin(), steps.end());
  if (*hi <= 1.01 * median && *lo >= 0.99 * median) return trace;
  const auto gap = static_cast<size_t>(hi - steps.begin());
  if (*hi > 2.5 * median) {
    char buf[256];
    std::snprintf(buf, sizeof buf,
                  "rows are missing: time_s steps by %.6g s after %.6g s, %.1f times the median "
                  "step of %.6g s; "
                  "the identification needs evenly spaced samples (cut the trace at the gap)",
                  *hi, trace.time_s[gap], *hi / median, median);
    const int line = gap + 1 < trace.row_line.size() ? trace.row_line[gap + 1] : 0;
    return located(buf, source, line, 1);
  }
  Trace even;
  even.metadata = trace.metadata;
  const double t0 = trace.time_s.front();
  const auto rows = static_cast<size_t>(std::floor((trace.time_s.back() - t0) / median + 1e-9)) + 1;
  even.time_s.resize(rows);
  for (size_t k = 0; k < rows; ++k) even.time_s[k] = t0 + static_cast<double>(k) * median;
  for (const AxisTrace& a : trace.axes) {
    AxisTrace& b = even.axes.emplace_back();
    b.name = a.name;
    b.cmd_mm.resize(rows);
    b.meas_mm.resize(rows);
  }
  size_t i = 0;  // the row at or before the grid time
  for (size_t k = 0; k < rows; ++k) {
    const double t = even.time_s[k];
    while (i + 2 < n && trace.time_s[i + 1] <= t) ++i;
    const double f =
        std::clamp((t - trace.time_s[i]) / (trace.time_s[i + 1] - trace.time_s[i]), 0.0, 1.0);
    for (size_t a = 0; a < trace.axes.size(); ++a) {
      const AxisTrace& src = trace.axes[a];
      even.axes[a].cmd_mm[k] = src.cmd_mm[i] + f * (src.cmd_mm[i + 1] - src.cmd_mm[i]);
      even.axes[a].meas_mm[k] = src.meas_mm[i] + f * (src.meas_mm[i + 1] - src.meas_mm[i]);
    }
  }
  if (note != nullptr) {
    char buf[256];
    std::snprintf(
        buf, sizeof buf,
        "time steps of %.6g-%.6g s: resampled onto an even %.6g s grid (the median step) by linear "
        "interpolation, %zu rows -> %zu samples",
        *lo, *hi, median, n, rows);
    *note = buf;
  }
  return even;
}

std::string format_trace_csv(const Trace& trace) {
  std::string out;
  char buf[64];
  for (const auto& [k, v] : trace.metadata) out += "# " + k + (v.empty() ? "" : "=" + v) + "\n";
  out += "time_s";
  for (const auto& a : trace.axes) out += "," + a.name + "_cmd_mm," + a.name + "_meas_mm";
  out += "\n";
  for (size_t i = 0; i < trace.time_s.size(); ++i) {
    std::snprintf(buf, sizeof buf, "%.6f", trace.time_s[i]);
    out += buf;
    for (const auto& a : trace.axes) {
      std::snprintf(buf, sizeof buf, ",%.7f,%.7f", a.cmd_mm[i], a.meas_mm[i]);
      out += buf;
    }
    out += "\n";
  }
  return out;
}

Status write_trace_csv(const std::string& path, const Trace& trace) {
  for (const auto& a : trace.axes)
    if (a.cmd_mm.size() != trace.time_s.size() || a.meas_mm.size() != trace.time_s.size())
      return Error{"axis '" + a.name + "' has a different number of samples than time_s", {}};
  std::ofstream f(path, std::ios::binary);
  if (!f) return Error{"cannot write trace file", SourceLocation{path, 0, 0}};
  f << format_trace_csv(trace);
  if (!f) return Error{"write failed", SourceLocation{path, 0, 0}};
  return Status::Ok();
}

}  // namespace feedloop::ident
