// External plant v1, the plant's side of the lines (see protocol.hpp).
#include "plant2/protocol.hpp"

#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace feedloop::plant2 {

namespace {

std::string quoted(std::string_view s) {
  constexpr size_t kMax = 80;
  std::string q(s.substr(0, kMax));
  if (s.size() > kMax) q += "...";
  return "'" + q + "'";
}

bool is_number_char(char c) {
  return std::isdigit(static_cast<unsigned char>(c)) || c == '.' || c == '-' || c == '+' ||
         c == 'e' || c == 'E';
}

// Parses one plain decimal number from exactly the characters of `tok`.
bool parse_number(std::string_view tok, double* out) {
  char buf[64];
  if (tok.empty() || tok.size() >= sizeof buf) return false;
  for (char c : tok)
    if (!is_number_char(c)) return false;
  tok.copy(buf, tok.size());
  buf[tok.size()] = '\0';
  char* end = nullptr;
  const double v = std::strtod(buf, &end);
  if (end != buf + tok.size() || !std::isfinite(v)) return false;
  *out = v;
  return true;
}

}  // namespace

Result<Handshake> parse_handshake(std::string_view line) {
  const std::string_view prefix = "feedloop-plant 1 axes=";
  auto bad = [&line](const std::string& why) {
    return Error{"handshake " + quoted(line) + ": " + why, {}};
  };
  if (line.substr(0, prefix.size()) != prefix)
    return bad("expected 'feedloop-plant 1 axes=... period_s=...'");
  std::string_view rest = line.substr(prefix.size());
  const size_t space = rest.find(' ');
  if (space == std::string_view::npos) return bad("missing period_s");
  std::string_view axes = rest.substr(0, space);
  std::string_view period = rest.substr(space + 1);
  Handshake h;
  while (!axes.empty()) {
    const size_t comma = axes.find(',');
    const std::string_view name = axes.substr(0, comma);
    if (name.empty()) return bad("empty axis name");
    for (char c : name)
      if (!std::isalnum(static_cast<unsigned char>(c))) return bad("axis names are letters");
    h.axes.emplace_back(name);
    if (comma == std::string_view::npos) break;
    axes = axes.substr(comma + 1);
    if (axes.empty()) return bad("empty axis name");
  }
  if (h.axes.empty()) return bad("no axes");
  const std::string_view pkey = "period_s=";
  if (period.substr(0, pkey.size()) != pkey) return bad("expected period_s=");
  if (!parse_number(period.substr(pkey.size()), &h.period_s) || !(h.period_s > 0.0))
    return bad("period_s must be a positive number");
  return h;
}

std::string parse_period_line(std::string_view line, size_t n, double* t_s, double* u) {
  size_t field = 0;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    if (i >= line.size()) break;
    size_t j = i;
    while (j < line.size() && line[j] != ' ' && line[j] != '\t') ++j;
    double v = 0.0;
    if (field > n) {
      return "expected " + std::to_string(n + 1) +
             " numbers (t_s and one per axis), got more: " + quoted(line);
    }
    if (!parse_number(line.substr(i, j - i), &v))
      return "field " + std::to_string(field + 1) + " is not a number: " + quoted(line);
    if (field == 0) {
      *t_s = v;
    } else {
      u[field - 1] = v;
    }
    ++field;
    i = j;
  }
  if (field != n + 1) {
    return "expected " + std::to_string(n + 1) + " numbers (t_s and one per axis), got " +
           std::to_string(field) + ": " + quoted(line);
  }
  return {};
}

void format_answer(const double* y, size_t n, std::string* out) {
  out->clear();
  char buf[40];
  for (size_t i = 0; i < n; ++i) {
    const int len = std::snprintf(buf, sizeof buf, i == 0 ? "%.12g" : " %.12g", y[i]);
    out->append(buf, static_cast<size_t>(len));
  }
  out->push_back('\n');
}

}  // namespace feedloop::plant2
