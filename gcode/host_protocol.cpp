// Marlin host protocol: sequence and checksum checks, replies, M110, M112 (see the header for the
// exact replies and the order of checks, which follow Marlin's GCodeQueue::get_serial_commands).
#include "gcode/host_protocol.hpp"

#include <charconv>
#include <cstdint>
#include <utility>

#include "gcode/parser.hpp"

namespace feedloop::gcode {
namespace {

bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }
bool is_digit(char c) { return c >= '0' && c <= '9'; }

void append_int(std::string& s, int64_t v) {
  char buf[24];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  s.append(buf, r.ptr);
}

// Digits at s[i...] as Marlin's strtol reads them (leading blanks skipped, no digits -> 0),
// saturating instead of overflowing.
int64_t read_long(std::string_view s, size_t i) {
  while (i < s.size() && is_blank(s[i])) ++i;
  bool negative = false;
  if (i < s.size() && (s[i] == '-' || s[i] == '+')) negative = s[i++] == '-';
  int64_t v = 0;
  for (; i < s.size() && is_digit(s[i]); ++i) {
    if (v > (INT64_MAX - 9) / 10) return negative ? INT64_MIN : INT64_MAX;
    v = v * 10 + (s[i] - '0');
  }
  return negative ? -v : v;
}

// "M110" (any case) not followed by another digit, anywhere in the text (Marlin: strstr).
bool mentions_m110(std::string_view s) {
  for (size_t i = 0; i + 4 <= s.size(); ++i) {
    if ((s[i] == 'M' || s[i] == 'm') && s.substr(i + 1, 3) == "110" &&
        (i + 4 == s.size() || !is_digit(s[i + 4])))
      return true;
  }
  return false;
}

// "...*<digits>" at the end of the text (blanks around the digits allowed): a checksum. A '*'
// inside M117 text ("5*5 grid") is not one.
bool has_checksum_tail(std::string_view s) {
  const size_t star = s.rfind('*');
  if (star == std::string_view::npos) return false;
  size_t i = star + 1;
  while (i < s.size() && is_blank(s[i])) ++i;
  const size_t digits = i;
  while (i < s.size() && is_digit(s[i])) ++i;
  if (i == digits) return false;
  while (i < s.size() && is_blank(s[i])) ++i;
  return i == s.size();
}

}  // namespace

HostProtocol::HostProtocol(std::string source_name) : HostProtocol(std::move(source_name), {}) {}

HostProtocol::HostProtocol(std::string source_name, Options options)
    : source_(std::move(source_name)), options_(options) {
  where_.source = source_;
}

uint8_t HostProtocol::checksum(std::string_view s) {
  uint8_t x = 0;
  for (const char c : s) x ^= static_cast<uint8_t>(c);
  return x;
}

namespace {
// `raw` is M<code> (3 digits), optionally after an N word: the emergency parser's commands.
bool is_immediate_m(std::string_view raw, std::string_view code) {
  size_t i = 0;
  const size_t n = raw.size();
  while (i < n && is_blank(raw[i])) ++i;
  if (i < n && (raw[i] == 'N' || raw[i] == 'n')) {
    ++i;
    while (i < n && is_digit(raw[i])) ++i;
    while (i < n && is_blank(raw[i])) ++i;
  }
  if (i + 4 > n || (raw[i] != 'M' && raw[i] != 'm') || raw.substr(i + 1, 3) != code) return false;
  return i + 4 == n || !(is_digit(raw[i + 4]) || raw[i + 4] == '.');
}
}  // namespace

bool HostProtocol::is_emergency_stop(std::string_view raw) {
  return is_immediate_m(raw, "112");
}
bool HostProtocol::is_break_and_continue(std::string_view raw) {
  return is_immediate_m(raw, "108");
}
bool HostProtocol::is_prompt_response(std::string_view raw) {
  return is_immediate_m(raw, "876");
}

void HostProtocol::line_error(std::string_view message, Reply& out) {
  out.text.append("Error:");
  out.text.append(message);
  append_int(out.text, last_n_);
  out.text.push_back('\n');
  out.text.append(kResend);
  append_int(out.text, last_n_ + 1);
  out.text.push_back('\n');
  out.line(kOk);
  ++stats_.resends_requested;
}

HostProtocol::Action HostProtocol::on_line(std::string_view raw, Reply& out, Command& command) {
  ++stats_.lines_received;
  ++physical_line_;
  command.clear();
  if (is_emergency_stop(raw)) return Action::kEmergencyStop;

  // The part Marlin keeps: leading blanks skipped, everything from ';' on dropped.
  size_t b = 0;
  while (b < raw.size() && is_blank(raw[b])) ++b;
  std::string_view body = raw.substr(b);
  if (const size_t semi = body.find(';'); semi != std::string_view::npos) body = body.substr(0, semi);
  size_t last = body.size();
  while (last > 0 && is_blank(body[last - 1])) --last;
  if (last == 0) return Action::kNone;  // blank or comment-only: no reply at all (Marlin)

  where_.line = physical_line_ > INT32_MAX ? 0 : static_cast<int>(physical_line_);
  Status parsed = parse_line(raw, where_, command);

  if (body[0] == 'N' || body[0] == 'n') {
    const bool m110 = parsed ? command.is('M', 110) : mentions_m110(body);
    const int64_t leading_n = read_long(body, 1);
    if (!m110 && leading_n != last_n_ + 1) {
      command.clear();
      line_error(kErrLineNo, out);
      return Action::kNone;
    }
    const size_t star = body.rfind('*');
    if (star == std::string_view::npos) {
      command.clear();
      line_error(kErrNoChecksum, out);
      return Action::kNone;
    }
    if (read_long(body, star + 1) != checksum(body.substr(0, star))) {
      command.clear();
      line_error(kErrChecksumMismatch, out);
      return Action::kNone;
    }
    last_n_ = (m110 && parsed && command.has_value('N'))
                  ? static_cast<int64_t>(command.get('N'))
                  : leading_n;
  } else if (has_checksum_tail(body)) {
    // A checksum needs a line number to go with it (Marlin 1.0.x, Marlin_main.cpp get_command():
    // "No Line Number with checksum"): nothing executes. Marlin then sends nothing more; here
    // the line gets its ok like every other refused line, so hosts that count oks go on.
    command.clear();
    ++stats_.parse_errors;
    out.text.append("Error:");
    out.text.append(kErrNoLineNumber);
    append_int(out.text, last_n_);
    out.text.push_back('\n');
    out.line(kOk);
    return Action::kNone;
  }

  if (!parsed) {
    ++stats_.parse_errors;
    out.text.append("Error:");
    out.text.append(parsed.error().to_string());
    out.text.push_back('\n');
    out.line(kOk);
    return Action::kNone;
  }
  if (command.is('M', 112)) return Action::kEmergencyStop;  // e.g. "(note) M112"
  if (command.is('M', 110)) {
    if (command.has_value('N')) last_n_ = static_cast<int64_t>(command.get('N'));
    command.clear();
    out.line(kOk);
    return Action::kNone;
  }
  if (command.empty()) {  // "N5" alone or "(comment)": accepted, nothing to do
    out.line(kOk);
    return Action::kNone;
  }
  if (command.unknown && options_.warn_unknown &&
      !(options_.caller_handles && options_.caller_handles(command))) {
    // Marlin prints the command as received, from after the line number.
    std::string_view shown = body;
    if (shown[0] == 'N' || shown[0] == 'n') {
      size_t k = 1;
      while (k < shown.size() && is_digit(shown[k])) ++k;
      while (k < shown.size() && is_blank(shown[k])) ++k;
      shown = shown.substr(k);
    }
    if (const size_t star = shown.rfind('*'); star != std::string_view::npos)
      shown = shown.substr(0, star);
    while (!shown.empty() && is_blank(shown.back())) shown.remove_suffix(1);
    out.text.append("echo:Unknown command: \"");
    out.text.append(shown);
    out.text.append("\"\n");
  }
  ++stats_.commands_executed;
  if (!options_.defer_ok) out.line(kOk);
  return Action::kExecute;
}

HostProtocol::Action HostProtocol::on_too_long(const SplitLine& line, Reply& out) {
  ++stats_.lines_received;
  ++physical_line_;
  ++stats_.parse_errors;
  out.text.append("Error:");
  out.text.append(source_);
  out.text.push_back(':');
  append_int(out.text, physical_line_);
  out.text.append(": line too long (");
  append_int(out.text, static_cast<int64_t>(line.length_bytes));
  out.text.append(" bytes); ignored\n");
  out.line(kOk);
  return Action::kNone;
}

}  // namespace feedloop::gcode
