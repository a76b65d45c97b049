#include "cli/print_lines.hpp"

#include <cstdio>
#include <string>

#include "gcode/host_protocol.hpp"
#include "gcode/parser.hpp"

namespace feedloop::cli {
namespace {

bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r'; }
bool is_digit(char c) { return c >= '0' && c <= '9'; }

std::string_view trim(std::string_view s) {
  while (!s.empty() && is_blank(s.back())) s.remove_suffix(1);
  while (!s.empty() && is_blank(s.front())) s.remove_prefix(1);
  return s;
}

bool starts_with(std::string_view s, std::string_view p) { return s.substr(0, p.size()) == p; }

// "M110" as a whole code word at the start of a command.
bool is_m110(std::string_view cmd) {
  if (cmd.size() < 4 || (cmd[0] != 'M' && cmd[0] != 'm') || cmd.substr(1, 3) != "110") return false;
  return cmd.size() == 4 || !is_digit(cmd[4]);
}

std::string format_number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.5f", v);
  std::string s(buf);
  while (!s.empty() && s.back() == '0') s.pop_back();
  if (!s.empty() && s.back() == '.') s.pop_back();
  if (s == "-0") s = "0";
  return s;
}

}  // namespace

std::string numbered_line(int64_t n, std::string_view cmd) {
  std::string s = "N" + std::to_string(n) + " ";
  s.append(cmd);
  s += "*" + std::to_string(gcode::HostProtocol::checksum(s));
  return s;
}

PreparedLine prepare_line(std::string_view raw) {
  PreparedLine out;
  std::string_view line = trim(raw);
  // A numbered line: N<digits>, then the command, then *<checksum> (Marlin's rules: the checksum
  // covers every byte before the last '*'; a ';' comment after the checksum is not covered).
  if (!line.empty() && (line[0] == 'N' || line[0] == 'n') && line.size() > 1 && is_digit(line[1])) {
    std::string_view body = line.substr(0, line.find(';'));
    const size_t star = body.rfind('*');
    size_t i = 1;
    while (i < body.size() && is_digit(body[i])) ++i;
    std::string_view cmd = body.substr(i, star == std::string_view::npos ? std::string_view::npos : star - i);
    if (star != std::string_view::npos) {
      std::string_view digits = trim(body.substr(star + 1));
      bool ok = !digits.empty() && digits.size() <= 3;
      unsigned value = 0;
      for (const char c : digits) {
        if (!is_digit(c)) ok = false;
        else value = value * 10 + static_cast<unsigned>(c - '0');
      }
      const unsigned expected = gcode::HostProtocol::checksum(body.substr(0, star));
      if (!ok || value != expected) {
        out.kind = PreparedLine::Kind::kBadChecksum;
        out.problem = "checksum in the file is " + std::string(digits) + ", the line's bytes give " +
                      std::to_string(expected) + "; line not sent";
        return out;
      }
    }
    line = trim(cmd);
  } else {
    line = trim(line.substr(0, line.find(';')));
  }
  if (line.empty() || is_m110(line)) return out;  // the client owns the line numbers
  out.kind = PreparedLine::Kind::kSend;
  out.command = std::string(line);
  return out;
}

ReplyKind classify_reply(std::string_view reply) {
  ReplyKind r;
  if (reply == "ok" || starts_with(reply, "ok ")) {
    r.kind = ReplyKind::Kind::kOk;
  } else if (starts_with(reply, gcode::HostProtocol::kResend)) {
    r.kind = ReplyKind::Kind::kResend;
    r.resend_n = 0;
    for (const char c : reply.substr(gcode::HostProtocol::kResend.size())) {
      if (!is_digit(c)) break;
      r.resend_n = r.resend_n * 10 + (c - '0');
    }
  } else if (starts_with(reply, "Error:")) {
    const std::string_view msg = reply.substr(6);
    // The protocol errors that a Resend follows: the line is sent again, not rejected.
    const bool resend = starts_with(msg, gcode::HostProtocol::kErrChecksumMismatch) ||
                        starts_with(msg, gcode::HostProtocol::kErrLineNo) ||
                        starts_with(msg, gcode::HostProtocol::kErrNoChecksum);
    r.kind = resend ? ReplyKind::Kind::kResendError : ReplyKind::Kind::kError;
  }
  return r;
}

std::string locate_error(std::string_view error_text, const std::string& file, int file_line) {
  std::string_view msg = error_text;
  if (starts_with(msg, "Error:")) msg.remove_prefix(6);
  // "<source>:<line>:<col>: message", the source without ':' or ' '.
  std::string col;
  const size_t c1 = msg.find(':');
  if (c1 != std::string_view::npos && c1 > 0 && msg.substr(0, c1).find(' ') == std::string_view::npos) {
    size_t i = c1 + 1, line_end = i;
    while (line_end < msg.size() && is_digit(msg[line_end])) ++line_end;
    if (line_end > i && line_end < msg.size() && msg[line_end] == ':') {
      size_t col_end = line_end + 1;
      while (col_end < msg.size() && is_digit(msg[col_end])) ++col_end;
      if (col_end > line_end + 1 && col_end < msg.size() && msg[col_end] == ':') {
        col = std::string(msg.substr(line_end + 1, col_end - line_end - 1));
        msg = trim(msg.substr(col_end + 1));
      } else {
        msg = trim(msg.substr(line_end + 1));
      }
    }
  }
  return file + ":" + std::to_string(file_line) + ":" + (col.empty() ? "" : col + ":") + " " + std::string(msg);
}

bool ResumeTracker::skip(std::string_view command) {
  gcode::Command c;
  if (!gcode::parse_line(command, SourceLocation{"resume", 0, 0}, c)) return false;
  if (c.letter == 'G') {
    switch (c.code) {
      case 0:
      case 1:
      case 2:
      case 3: {
        static constexpr char kAxes[4] = {'X', 'Y', 'Z', 'E'};
        for (int a = 0; a < 4; ++a) {
          if (!c.has_value(kAxes[a])) continue;
          const bool absolute = a == 3 ? absolute_e_ : absolute_xyz_;
          pos_[a] = absolute ? c.get(kAxes[a]) : pos_[a] + c.get(kAxes[a]);
          known_[a] = true;
        }
        if (c.has_value('F')) feed_mm_min_ = c.get('F');
        return false;
      }
      case 90: absolute_xyz_ = absolute_e_ = true; return true;
      case 91: absolute_xyz_ = absolute_e_ = false; return true;
      case 92:
        for (int a = 0; a < 4; ++a) {
          static constexpr char kAxes[4] = {'X', 'Y', 'Z', 'E'};
          if (c.has_value(kAxes[a])) {
            pos_[a] = c.get(kAxes[a]);
            known_[a] = true;
          }
        }
        return true;
      case 28:
        for (int a = 0; a < 3; ++a) {
          static constexpr char kAxes[3] = {'X', 'Y', 'Z'};
          if (!c.has('X') && !c.has('Y') && !c.has('Z')) pos_[a] = 0, known_[a] = true;
          else if (c.has(kAxes[a])) pos_[a] = 0, known_[a] = true;
        }
        return true;
      case 4:  // dwell: not needed to resume
        return false;
      default: return true;  // units, planes, ...
    }
  }
  if (c.letter == 'M') {
    switch (c.code) {
      case 82: absolute_e_ = true; return true;
      case 83: absolute_e_ = false; return true;
      case 73:   // progress
      case 117:  // display message
      case 105:  // temperature query
      case 114:
      case 400:
        return false;
      default: return true;  // temperatures, fan, limits, ...
    }
  }
  return true;  // T<n>
}

std::string ResumeTracker::preamble() const {
  std::string out;
  // Lift to the resume height (or keep Z) before the horizontal move, then restore E.
  out += "G90\n";
  const std::string f = feed_mm_min_ > 0 ? " F" + format_number(feed_mm_min_) : "";
  if (known_[2]) out += "G1 Z" + format_number(pos_[2]) + " F600\n";
  if (known_[0] || known_[1]) {
    out += "G1";
    if (known_[0]) out += " X" + format_number(pos_[0]);
    if (known_[1]) out += " Y" + format_number(pos_[1]);
    out += " F3000\n";
  }
  if (known_[3]) out += "G92 E" + format_number(pos_[3]) + "\n";
  if (!absolute_xyz_) out += "G91\n";
  if (!absolute_e_) out += "M83\n";
  else if (absolute_xyz_ == false) out += "M82\n";
  if (!f.empty()) out += "G1" + f + "\n";
  return out;
}

}  // namespace feedloop::cli
