// Predicted-FRF CSV writer and reader (see frf_csv.hpp).
#include "model/frf_csv.hpp"

#include <array>
#include <charconv>  // std::from_chars
#include <cmath>     // std::isfinite
#include <cstdio>    // std::snprintf
#include <fstream>
#include <sstream>
#include <vector>

namespace feedloop::model {
namespace {

constexpr char kNames[3] = {'A', 'B', 'C'};

std::string column_name(int i, int j, bool imag) {
  return std::string(1, kNames[i]) + "_" + std::string(1, kNames[j]) + (imag ? "_im" : "_re");
}

std::vector<std::string> split_csv(const std::string& line) {
  std::vector<std::string> out;
  std::string cur;
  for (char ch : line) {
    if (ch == ',') {
      out.push_back(cur);
      cur.clear();
    } else if (ch != '\r') {
      cur.push_back(ch);
    }
  }
  out.push_back(cur);
  return out;
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return {};
  const auto e = s.find_last_not_of(" \t");
  return s.substr(b, e - b + 1);
}

}  // namespace

Status write_frf_csv(const std::string& path, const FrfSet& set) {
  if (set.h.size() != set.freq_hz.size()) return Error{"FRF set has mismatched sizes", {path, 0, 0}};
  std::ofstream out(path);
  if (!out) return Error{"cannot open for writing", {path, 0, 0}};
  out << "freq_hz";
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) out << ',' << column_name(i, j, false) << ',' << column_name(i, j, true);
  out << '\n';
  char buf[40];
  for (size_t k = 0; k < set.freq_hz.size(); ++k) {
    if (!std::isfinite(set.freq_hz[k]) || !set.h[k].allFinite())
      return Error{"FRF value is not finite at " + std::to_string(set.freq_hz[k]) + " Hz", {path, 0, 0}};
    std::snprintf(buf, sizeof buf, "%.10g", set.freq_hz[k]);
    out << buf;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        std::snprintf(buf, sizeof buf, ",%.12g", set.h[k](i, j).real());
        out << buf;
        std::snprintf(buf, sizeof buf, ",%.12g", set.h[k](i, j).imag());
        out << buf;
      }
    out << '\n';
  }
  out.flush();
  if (!out) return Error{"write failed", {path, 0, 0}};
  return {};
}

Status write_frf_csv(const std::string& path, const DeltaLpvModel& model, const Eigen::Vector3d& pos_mm,
                     const FrequencyGrid& grid) {
  auto set = model.frf(pos_mm, grid);
  if (!set) return set.error();
  return write_frf_csv(path, *set);
}

Result<FrfSet> read_frf_csv(const std::string& path) {
  std::ifstream in(path);
  if (!in) return Error{"cannot open for reading", {path, 0, 0}};
  std::string line;
  int line_no = 0;
  std::vector<std::string> header;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty() || line[0] == '#') continue;
    header = split_csv(line);
    break;
  }
  if (header.empty()) return Error{"no header row", {path, line_no, 0}};
  auto find = [&](const std::string& name) -> int {
    for (size_t c = 0; c < header.size(); ++c)
      if (trim(header[c]) == name) return static_cast<int>(c);
    return -1;
  };
  const int fcol = find("freq_hz");
  if (fcol < 0) return Error{"missing column freq_hz", {path, line_no, 0}};
  std::array<int, 18> cols{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int im = 0; im < 2; ++im) {
        const std::string name = column_name(i, j, im == 1);
        const int c = find(name);
        if (c < 0) return Error{"missing column " + name, {path, line_no, 0}};
        cols[static_cast<size_t>((i * 3 + j) * 2 + im)] = c;
      }
  FrfSet set;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty() || line[0] == '#') continue;
    const auto cells = split_csv(line);
    auto num = [&](int c, double& v) -> Status {
      if (c >= static_cast<int>(cells.size()))
        return Error{"row has only " + std::to_string(cells.size()) + " columns", {path, line_no, 0}};
      const std::string t = trim(cells[static_cast<size_t>(c)]);
      const auto r = std::from_chars(t.data(), t.data() + t.size(), v);
      if (r.ec != std::errc() || r.ptr != t.data() + t.size() || !std::isfinite(v))
        return Error{"not a finite number: '" + t + "'", {path, line_no, c + 1}};
      return {};
    };
    double f = 0.0;
    if (Status st = num(fcol, f); !st) return st.error();
    if (!set.freq_hz.empty() && f <= set.freq_hz.back())
      return Error{"freq_hz does not increase", {path, line_no, fcol + 1}};
    Eigen::Matrix3cd h;
    for (int e = 0; e < 9; ++e) {
      double re = 0.0, im = 0.0;
      if (Status st = num(cols[static_cast<size_t>(2 * e)], re); !st) return st.error();
      if (Status st = num(cols[static_cast<size_t>(2 * e + 1)], im); !st) return st.error();
      h(e / 3, e % 3) = {re, im};
    }
    set.freq_hz.push_back(f);
    set.h.push_back(h);
  }
  if (set.freq_hz.empty()) return Error{"no data rows", {path, line_no, 0}};
  return set;
}

}  // namespace feedloop::model
