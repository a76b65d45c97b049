// The G-code line parser: words -> Command, then validation against gcode/code_table. One pass
// over the bytes, no allocation on the success path (Command::clear keeps string storage).
#include "gcode/parser.hpp"

#include <array>
#include <bit>
#include <climits>
#include <cmath>
#include <cstdio>
#include <string>

#include "gcode/code_table.hpp"
#include "core/utf8.hpp"
#include "gcode/number.hpp"

namespace feedloop::gcode {
namespace {

inline bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }
inline bool is_alpha(char c) {
  const char l = static_cast<char>(c | 0x20);
  return l >= 'a' && l <= 'z';
}
inline char to_upper(char c) { return static_cast<char>(c & ~0x20); }  // only for letters

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

// "nan", "inf" or "infinity" (any case, an optional sign before it) at `pos`, as a word of its
// own: its length, else 0. G-code numbers are finite decimals; "X1e400" or "Xnan" from a host's
// formatting bug is a clear error, not letters read as flags ("Xnan" would be X, N, A, N).
size_t non_finite_word(std::string_view s, size_t pos) {
  size_t b = pos;
  if (b < s.size() && (s[b] == '+' || s[b] == '-')) ++b;
  for (std::string_view w :
       {std::string_view("infinity"), std::string_view("inf"), std::string_view("nan")}) {
    if (s.size() - b < w.size()) continue;
    bool same = true;
    for (size_t k = 0; k < w.size() && same; ++k) same = (s[b + k] | 0x20) == w[k];
    if (same && (b + w.size() == s.size() || !is_alpha(s[b + w.size()]))) return b + w.size() - pos;
  }
  return 0;
}

std::string describe_char(char c) {
  const auto u = static_cast<unsigned char>(c);
  char buf[32];
  if (u >= 0x21 && u < 0x7f) std::snprintf(buf, sizeof buf, "unexpected character '%c'", c);
  else std::snprintf(buf, sizeof buf, "unexpected byte 0x%02X", u);
  return buf;
}

// The command's name as written in messages: "G1", "M104", "G29.1", "T0".
std::string command_name(const Command& c) {
  std::string s(1, c.letter);
  s += std::to_string(c.code);
  if (c.subcode >= 0) s += "." + std::to_string(c.subcode);
  return s;
}

// Trims whitespace and a trailing "*<checksum>" from a free-text argument (the host protocol
// verified the checksum; a '*' not followed by only digits belongs to the text).
std::string_view trim_text(std::string_view t) {
  const size_t star = t.rfind('*');
  if (star != std::string_view::npos) {
    size_t j = star + 1;
    while (j < t.size() && is_space(t[j])) ++j;
    const size_t digits_start = j;
    while (j < t.size() && is_digit(t[j])) ++j;
    while (j < t.size() && is_space(t[j])) ++j;
    if (j == t.size() && j > digits_start) t = t.substr(0, star);
  }
  while (!t.empty() && is_space(t.front())) t.remove_prefix(1);
  while (!t.empty() && is_space(t.back())) t.remove_suffix(1);
  return t;
}

class LineParser {
 public:
  LineParser(std::string_view line, const SourceLocation& where, Command& out)
      : s_(line), where_(where), out_(out) {}

  Status run();

 private:
  Status fail(size_t pos, std::string message) const {
    SourceLocation at = where_;
    at.column = pos >= static_cast<size_t>(INT_MAX) ? INT_MAX : static_cast<int>(pos + 1);
    return Error{std::move(message), std::move(at)};
  }
  Status parse_words();
  Status parse_line_number(size_t word);
  Status parse_command_code(size_t word, char letter);
  Status parse_parameter(size_t word, char letter, bool after_space);
  Status check_checksum_tail(size_t star) const;
  Status reject_extended_command(size_t word) const;
  // Klipper's SET_PRESSURE_ADVANCE: true when the word is that command (then *st is the outcome).
  bool parse_pressure_advance(size_t word, Status* st);
  // Klipper's EXCLUDE_OBJECT_DEFINE / _START / _END and EXCLUDE_OBJECT: true when the word is one
  // of them (then *st is the outcome).
  bool parse_exclude_object(size_t word, Status* st);
  // The next NAME= of a Klipper extended command's parameters: skips blanks, reads the name
  // (upper-cased) and the '='. False at the line's end: a comment, or a checksum tail (*st then
  // says whether it was right), else *st is Ok; also false, with *st failed ("<command> takes
  // NAME=value parameters<hint>"), on a word that is not NAME=.
  bool next_extended_key(std::string_view command, std::string_view hint, size_t* key,
                         std::string* name, Status* st);
  // Marlin's own M486 (index form) into the Klipper forms' subcodes: Ok and the command
  // unchanged when it is not one of them (it stays unknown).
  Status translate_marlin_object_label();
  // An object's name (M486 A<name>; RepRapFirmware's M486 S<i> A"name"): true when the line is
  // one (then *st is the outcome).
  bool parse_object_name(Status* st);
  // The command kept (letter, code, line number), its parameters and text dropped: M486 as the
  // object-label form `subcode`, known.
  void restart_as_object_label(int subcode);
  Status validate() const;
  Status check_parameter(const CodeRule& rule, const ParamRule& p, char letter) const;
  void keep_as_text();  // an unknown command whose argument is not G-code words
  // The command's argument as text: from its code to a comment, trimmed (trim_text).
  std::string_view argument_text() const {
    const size_t semicolon = s_.find(';', code_end_);
    return trim_text(s_.substr(code_end_, semicolon == std::string_view::npos
                                              ? std::string_view::npos
                                              : semicolon - code_end_));
  }

  std::string_view s_;
  const SourceLocation& where_;
  Command& out_;
  size_t i_ = 0;
  size_t command_pos_ = 0;              // index of the command letter
  size_t code_end_ = 0;                 // index just past the command code
  std::array<uint32_t, 26> column_{};   // byte index of each parameter's letter
  bool extended_ = false;               // a Klipper command translated (validated on its own)
};

Status LineParser::run() {
  Status st = parse_words();
  // An object's name is free text, whatever letters, quotes or stars it holds: its words are not
  // parameters (nor is their failure the line's).
  if (out_.is('M', 486) && out_.subcode < 0 && !extended_) {
    Status named = Status::Ok();
    if (parse_object_name(&named)) {
      if (!named) out_.clear();
      return named;
    }
  }
  if (!st) {
    // An unknown command whose argument is not G-code words (a file name, a message) keeps the
    // argument as text instead of failing: unknown commands are the caller's business.
    if (out_.letter != 0 && out_.unknown && out_.text.empty()) {
      keep_as_text();
      return Status::Ok();
    }
    out_.clear();
    return st;
  }
  if (out_.letter == 0) return Status::Ok();  // blank, comment only, or just a line number
  if (extended_) return Status::Ok();
  if (out_.is('M', 486) && out_.subcode < 0) {
    Status marlin = translate_marlin_object_label();
    if (!marlin) out_.clear();
    return marlin;
  }
  Status valid = validate();
  if (!valid) out_.clear();
  return valid;
}

Status LineParser::parse_words() {
  const size_t n = s_.size();
  bool after_space = true;  // the current word starts the line or follows whitespace/a comment
  while (i_ < n) {
    const char c = s_[i_];
    if (is_space(c)) {
      ++i_;
      after_space = true;
      continue;
    }
    if (c == ';') return Status::Ok();
    if (c == '(') {
      const size_t close = s_.find(')', i_ + 1);
      if (close == std::string_view::npos) return fail(i_, "unclosed '(' comment");
      i_ = close + 1;
      after_space = true;
      continue;
    }
    if (c == '*') return check_checksum_tail(i_);
    if (!is_alpha(c)) return fail(i_, describe_char(c));
    const size_t word = i_;
    const char letter = to_upper(c);
    ++i_;
    if (out_.letter == 0) {
      if (letter == 'N' && out_.line_number < 0 && !out_.has_any_parameter()) {
        Status st = parse_line_number(word);
        if (!st) return st;
      } else if (letter == 'G' || letter == 'M' || letter == 'T') {
        Status st = parse_command_code(word, letter);
        if (!st) return st;
        if (is_text_command(out_.letter, out_.code)) {
          assign_valid_utf8(out_.text, argument_text());  // the outside-string boundary
          return Status::Ok();
        }
      } else {
        Status pa;
        if (parse_pressure_advance(word, &pa)) return pa;
        if (parse_exclude_object(word, &pa)) return pa;
        if (Status st = reject_extended_command(word); !st) return st;
        return fail(word, std::string("parameter ") + letter +
                              " before any command (expected G, M or T first)");
      }
    } else {
      if ((letter == 'G' || letter == 'M') && !out_.unknown)
        return fail(word, "only one command per line (" + command_name(out_) + " already given)");
      Status st = parse_parameter(word, letter, after_space);
      if (!st) return st;
    }
    after_space = false;
  }
  return Status::Ok();
}

// Printrun starts every print with "N-1 M110*..": a negative line number is accepted (the host
// protocol then expects N0 next, as Marlin does).
Status LineParser::parse_line_number(size_t word) {
  const size_t n = s_.size();
  const bool negative = i_ < n && s_[i_] == '-';
  if (negative) ++i_;
  if (i_ >= n || !is_digit(s_[i_])) return fail(word, "N needs a line number, e.g. N42");
  int64_t v = 0;
  while (i_ < n && is_digit(s_[i_])) {
    if (v > (INT64_MAX - 9) / 10) return fail(word, "line number too large");
    v = v * 10 + (s_[i_] - '0');
    ++i_;
  }
  out_.line_number = negative ? -v : v;
  return Status::Ok();
}

Status LineParser::parse_command_code(size_t word, char letter) {
  constexpr int kMaxCode = 99999;
  const size_t n = s_.size();
  if (i_ >= n || !is_digit(s_[i_]))
    return fail(word, std::string(1, letter) + " needs a code number, e.g. " + letter + "1");
  int code = 0;
  while (i_ < n && is_digit(s_[i_])) {
    code = code * 10 + (s_[i_] - '0');
    if (code > kMaxCode) return fail(word, "command number too large");
    ++i_;
  }
  int subcode = -1;
  if (i_ < n && s_[i_] == '.' && letter != 'T') {
    ++i_;
    if (i_ >= n || !is_digit(s_[i_])) return fail(word, "missing subcode after '.'");
    subcode = 0;
    while (i_ < n && is_digit(s_[i_])) {
      subcode = subcode * 10 + (s_[i_] - '0');
      if (subcode > kMaxCode) return fail(word, "command subcode too large");
      ++i_;
    }
  }
  out_.letter = letter;
  out_.code = code;
  out_.subcode = subcode;
  out_.unknown = subcode >= 0 || find_code_rule(letter, code) == nullptr;
  command_pos_ = word;
  code_end_ = i_;
  return Status::Ok();
}

Status LineParser::parse_parameter(size_t word, char letter, bool after_space) {
  const size_t n = s_.size();
  const int b = letter - 'A';
  if (out_.has(letter)) return fail(word, std::string(1, letter) + " given twice");
  column_[b] = static_cast<uint32_t>(word > UINT32_MAX ? UINT32_MAX : word);
  // Marlin skips blanks between a parameter letter and its value ("G1 X 30" is X30;
  // Marlin/src/gcode/parser.cpp, GCodeParser::parse); without a number after them the letter is
  // a flag ("G28 X Y").
  size_t value = i_;
  while (value < n && (s_[value] == ' ' || s_[value] == '\t')) ++value;
  if (value < n && value > i_) {
    const char c = s_[value];
    const bool numeric = is_digit(c) || (c == '.' && value + 1 < n && is_digit(s_[value + 1])) ||
                         ((c == '+' || c == '-') && value + 1 < n &&
                          (is_digit(s_[value + 1]) || s_[value + 1] == '.'));
    if (numeric) i_ = value;
  }
  if (const size_t len = non_finite_word(s_, value); len > 0)
    return fail(word, std::string(1, letter) + ": '" + std::string(s_.substr(value, len)) +
                          "' is not a number (G-code takes finite decimals)");
  if (i_ < n) {
    const char c = s_[i_];
    if (is_digit(c) || c == '.' || c == '+' || c == '-') {
      const NumberScan num = scan_number(s_, i_, after_space);
      if (num.status == NumberScan::Status::kNoDigits)
        return fail(word, std::string("bad number after ") + letter);
      if (num.status == NumberScan::Status::kOutOfRange)
        return fail(word, std::string("number after ") + letter + " out of range");
      i_ = num.end;
      out_.set(letter, num.value);
      return Status::Ok();
    }
  }
  out_.set_flag(letter);
  return Status::Ok();
}

// Klipper's extended commands ("SET_VELOCITY_LIMIT VELOCITY=300") are not G-code: Marlin answers
// them with "echo:Unknown command" (Marlin/src/gcode/gcode.cpp, process_parsed_command), which
// hosts hide, and the parameter-before-command message would mislead. Name the dialect and the
// Marlin codes that do the same.
Status LineParser::reject_extended_command(size_t word) const {
  size_t end = word;
  while (end < s_.size() && (is_alpha(s_[end]) || is_digit(s_[end]) || s_[end] == '_')) ++end;
  const std::string_view name = s_.substr(word, end - word);
  size_t letters = 0;
  while (letters < name.size() && (is_alpha(name[letters]) || name[letters] == '_')) ++letters;
  if (letters < 4 && name.find('_') == std::string_view::npos) return Status::Ok();
  std::string upper;
  for (const char c : name) upper.push_back(to_upper(c));
  std::string message = "'" + upper + "' is a Klipper extended command, not G-code; feedloop speaks Marlin G-code";
  if (upper == "SET_VELOCITY_LIMIT")
    message += " (limits: M203 max feed rate, M201/M204 acceleration, M205 junction deviation)";
  else if (upper == "SET_HEATER_TEMPERATURE")
    message += " (M104/M140 set temperatures)";
  else if (upper == "PAUSE" || upper == "RESUME" || upper == "CANCEL_PRINT")
    message += " (the host pauses or cancels by not sending; M112 stops at once)";
  return fail(word, message);
}

bool LineParser::next_extended_key(std::string_view command, std::string_view hint, size_t* key,
                                   std::string* name, Status* st) {
  const size_t n = s_.size();
  while (i_ < n && is_space(s_[i_])) ++i_;
  *st = Status::Ok();
  if (i_ >= n || s_[i_] == ';') return false;
  if (s_[i_] == '*') {
    *st = check_checksum_tail(i_);
    return false;
  }
  *key = i_;
  while (i_ < n && (is_alpha(s_[i_]) || s_[i_] == '_')) ++i_;
  name->clear();
  for (size_t k = *key; k < i_; ++k) name->push_back(to_upper(s_[k]));
  if (name->empty() || i_ >= n || s_[i_] != '=') {
    *st = fail(*key, std::string(command) + " takes NAME=value parameters" + std::string(hint));
    return false;
  }
  ++i_;
  return true;
}

// Klipper's object labels (Klipper docs G-Codes.md, [exclude_object]), which slicers write for a
// Klipper printer ("label objects: firmware-specific"), parsed into M486 with a subcode for the
// form (gcode/command.hpp, ObjectLabelForm) and the object's NAME, upper-cased as Klipper does, in
// `text`:
//   EXCLUDE_OBJECT_DEFINE NAME=n [CENTER=x,y] [POLYGON=[[x,y],...]] | RESET=1   M486.1 (R: reset)
//   EXCLUDE_OBJECT_START NAME=n                                                 M486.2
//   EXCLUDE_OBJECT_END [NAME=n]                                                 M486.3
//   EXCLUDE_OBJECT [NAME=n | CURRENT=1 | RESET=1]                                M486.4 (C, R)
// CENTER and POLYGON are checked for form only (the web map is not drawn from them). A value may
// be quoted ('a b' or "a b"); a POLYGON's brackets may hold blanks.
bool LineParser::parse_exclude_object(size_t word, Status* st) {
  const size_t n = s_.size();
  size_t end = word;
  while (end < n && (is_alpha(s_[end]) || is_digit(s_[end]) || s_[end] == '_')) ++end;
  // Indexed by ObjectLabelForm. Compared in place, case-insensitively: no allocation.
  static constexpr std::string_view kForms[] = {"", "EXCLUDE_OBJECT_DEFINE", "EXCLUDE_OBJECT_START",
                                                "EXCLUDE_OBJECT_END", "EXCLUDE_OBJECT"};
  int form = 0;
  for (int f = kObjectDefine; f <= kObjectExclude && form == 0; ++f) {
    const std::string_view candidate = kForms[f];
    bool same = end - word == candidate.size();
    for (size_t k = 0; same && k < candidate.size(); ++k)
      same = (is_alpha(s_[word + k]) ? to_upper(s_[word + k]) : s_[word + k]) == candidate[k];
    if (same) form = f;
  }
  if (form == 0) return false;
  const std::string_view upper = kForms[form];
  out_.letter = 'M';
  out_.code = 486;
  out_.subcode = form;
  command_pos_ = word;
  extended_ = true;
  i_ = end;
  bool have_name = false;
  size_t key = 0;
  std::string name;
  while (next_extended_key(upper, "", &key, &name, st)) {
    // The value: quoted, or up to a blank outside brackets.
    std::string_view value;
    const size_t v = i_;
    if (i_ < n && (s_[i_] == '\'' || s_[i_] == '"')) {
      const char q = s_[i_];
      const size_t close = s_.find(q, i_ + 1);
      if (close == std::string_view::npos) {
        *st = fail(v, std::string(upper) + ": unclosed quote in " + name);
        return true;
      }
      value = s_.substr(i_ + 1, close - i_ - 1);
      i_ = close + 1;
    } else {
      int depth = 0;
      while (i_ < n && s_[i_] != ';' && (depth > 0 || (!is_space(s_[i_]) && s_[i_] != '*'))) {
        depth += s_[i_] == '[' ? 1 : s_[i_] == ']' ? -1 : 0;
        ++i_;
      }
      value = s_.substr(v, i_ - v);
    }
    const bool known =
        name == "NAME" ||
        (form == kObjectDefine && (name == "CENTER" || name == "POLYGON" || name == "RESET")) ||
        (form == kObjectExclude && (name == "CURRENT" || name == "RESET"));
    if (!known) {
      *st = fail(key, std::string(upper) + ": unknown parameter " + name);
      return true;
    }
    if (name == "NAME") {
      if (have_name) {
        *st = fail(key, std::string(upper) + ": NAME given twice");
        return true;
      }
      if (value.empty()) {
        *st = fail(v, std::string(upper) + ": NAME needs a value");
        return true;
      }
      assign_valid_utf8(out_.text, value);  // the outside-string boundary
      for (char& c : out_.text)
        if (is_alpha(c)) c = to_upper(c);
      have_name = true;
    } else if (name == "CURRENT" || name == "RESET") {
      if (value != "1" && value != "0") {
        *st = fail(v, std::string(upper) + ": " + name + " takes 1 or 0");
        return true;
      }
      if (value == "1") out_.set_flag(name == "CURRENT" ? 'C' : 'R');
    }
  }
  if (!*st) return true;
  const bool needs_name = form == kObjectStart || (form == kObjectDefine && !out_.has('R'));
  if (needs_name && !have_name) {
    *st = fail(word, std::string(upper) + " needs NAME=<object>");
    return true;
  }
  if (form == kObjectExclude && have_name + out_.has('C') + out_.has('R') > 1) {
    *st = fail(word, "EXCLUDE_OBJECT takes one of NAME=, CURRENT=1 and RESET=1");
    return true;
  }
  *st = Status::Ok();
  return true;
}

// Marlin's own object labels (Marlin's M486, CANCEL_OBJECTS), which PrusaSlicer writes for a
// Marlin printer ("label objects: firmware-specific"), into the Klipper forms above; an
// object's name is its index ("0", "1", ...):
//   M486 T<count>   M486.1 R    a new plate: nothing defined or excluded (the count is not kept)
//   M486 S<i>       M486.2 i    the moves that follow are object i's (defines it)
//   M486 S-1        M486.3      the moves that follow belong to no object (a purge line, a brim)
//   M486 P<i>       M486.4 i    object i is skipped from now on
//   M486 C          M486.4 C    the current object is skipped from now on
// One of T, S, P and C per line (no slicer writes more). U<i> (Marlin's un-cancel) is refused:
// an excluded object stays excluded until the print ends, as in Klipper. The object's name,
// which PrusaSlicer writes after the S in a line of its own ("M486 AShape-Box id:0 copy 0"), is
// parse_object_name()'s; an A that is not a word of its own ("M486 S1A") leaves the line unknown.
// The command keeps no parameter but the Klipper forms' flags (R, C).
Status LineParser::translate_marlin_object_label() {
  if (out_.has('A')) return Status::Ok();
  if (out_.has('U'))
    return fail(column_['U' - 'A'],
                "M486 U (un-cancel an object) is not supported: an excluded object stays "
                "excluded until the print ends");
  const int forms = out_.has('T') + out_.has('S') + out_.has('P') + out_.has('C');
  if (forms == 0) return Status::Ok();  // "M486", "M486 A<name>": nothing to do here
  if (forms > 1) return fail(command_pos_, "M486: one of T, S, P and C per line");
  auto index = [&](char letter, int lowest, int* out) -> Status {
    const double v = out_.get(letter, NAN);
    if (!out_.has_value(letter) || !(v >= lowest && v <= 1e6) || v != std::floor(v))
      return fail(column_[letter - 'A'], std::string("M486 ") + letter +
                                             " takes an object index (" +
                                             (lowest < 0 ? "-1 or " : "") + "0, 1, 2, ...)");
    *out = static_cast<int>(v);
    return Status::Ok();
  };
  int i = 0;
  if (out_.has('T')) {
    if (Status st = index('T', 0, &i); !st) return st;
    restart_as_object_label(kObjectDefine);
    out_.set_flag('R');
  } else if (out_.has('S')) {
    if (Status st = index('S', -1, &i); !st) return st;
    restart_as_object_label(i < 0 ? kObjectEnd : kObjectStart);
    if (i >= 0) out_.text = std::to_string(i);
  } else if (out_.has('P')) {
    if (Status st = index('P', 0, &i); !st) return st;
    restart_as_object_label(kObjectExclude);
    out_.text = std::to_string(i);
  } else {
    restart_as_object_label(kObjectExclude);
    out_.set_flag('C');  // the current object
  }
  return Status::Ok();
}

void LineParser::restart_as_object_label(int subcode) {
  const int64_t line_number = out_.line_number;
  out_.clear();
  out_.letter = 'M';
  out_.code = 486;
  out_.subcode = subcode;
  out_.line_number = line_number;
}

// An object's name, as PrusaSlicer writes it with "label objects: firmware-specific": for Marlin
// on a line of its own after the object's S ("M486 AShape-Box id:0 copy 0"), for RepRapFirmware
// on the S line, quoted ("M486 S3 A\"cube copy 3\""). The name is the rest of the line after the
// A (a comment and a verified checksum left out; one pair of enclosing quotes taken off); it names
// the current object, or, with S, object S, which starts (M486.5; the name in `text`, the index
// in S). The name is upper-cased as Klipper's are, and a blank, quote, star, semicolon or bracket
// in it becomes '_', so that Mainsail's and Fluidd's "exclude object" sends it back as one
// EXCLUDE_OBJECT NAME= value. "M486 A" (no name) stays unknown, ignored; "M486 S<i> A" is S<i>.
bool LineParser::parse_object_name(Status* st) {
  const std::string_view arg = argument_text();
  const size_t arg_pos = static_cast<size_t>(arg.data() - s_.data());
  size_t a = std::string_view::npos;  // the A word: the argument's first, or after a blank
  for (size_t k = 0; k < arg.size() && a == std::string_view::npos; ++k)
    if ((arg[k] == 'A' || arg[k] == 'a') && (k == 0 || is_space(arg[k - 1]))) a = k;
  if (a == std::string_view::npos) return false;
  // Before the A: nothing (Marlin), or S<index> (RepRapFirmware).
  std::string_view before = trim_text(arg.substr(0, a));
  int index = -2;  // none
  if (!before.empty()) {
    const auto bad = [&] {
      *st = fail(arg_pos, "M486: an object's name (A) goes on a line of its own or after S<index>");
      return true;
    };
    if (before.front() != 'S' && before.front() != 's') return bad();
    before = trim_text(before.substr(1));
    const bool negative = !before.empty() && before.front() == '-';
    if (negative) before.remove_prefix(1);
    if (before.empty() || before.size() > 7) return bad();
    int v = 0;
    for (const char c : before) {
      if (!is_digit(c)) return bad();
      v = v * 10 + (c - '0');
    }
    if (negative && v != 1) return bad();
    index = negative ? -1 : v;
  }
  std::string_view name = trim_text(arg.substr(a + 1));
  if (name.size() >= 2 && (name.front() == '"' || name.front() == '\'') &&
      name.back() == name.front())
    name = trim_text(name.substr(1, name.size() - 2));
  if (index == -1) {  // "M486 S-1 A...": no object; a name for none is nothing
    restart_as_object_label(kObjectEnd);
    return true;
  }
  if (name.empty()) {
    if (index < 0) return false;  // "M486 A": nothing named
    restart_as_object_label(kObjectStart);
    out_.text = std::to_string(index);
    return true;
  }
  restart_as_object_label(kObjectName);
  assign_valid_utf8(out_.text, name);  // the outside-string boundary
  for (char& c : out_.text) {
    if (is_alpha(c))
      c = to_upper(c);
    else if (is_space(c) || c == '"' || c == '\'' || c == '*' || c == ';' || c == '[' || c == ']')
      c = '_';
  }
  if (index >= 0) out_.set('S', index);
  return true;
}

// Klipper's SET_PRESSURE_ADVANCE [EXTRUDER=extruder] [ADVANCE=<s>] [SMOOTH_TIME=<s>] (Klipper
// docs G-Codes.md, [extruder]): parsed into M900 with text "SET_PRESSURE_ADVANCE", K = ADVANCE,
// S = SMOOTH_TIME; the interpreter checks the ranges (planner/interpreter.cpp). Parameter names
// are case-insensitive as in Klipper; each NAME=value once; numbers only.
bool LineParser::parse_pressure_advance(size_t word, Status* st) {
  constexpr std::string_view kName = "SET_PRESSURE_ADVANCE";
  const size_t n = s_.size();
  size_t end = word;
  while (end < n && (is_alpha(s_[end]) || is_digit(s_[end]) || s_[end] == '_')) ++end;
  if (end - word != kName.size()) return false;
  for (size_t k = 0; k < kName.size(); ++k) {
    const char c = s_[word + k];
    if ((is_alpha(c) ? to_upper(c) : c) != kName[k]) return false;
  }
  out_.letter = 'M';
  out_.code = 900;
  out_.text.assign(kName);
  command_pos_ = word;
  extended_ = true;
  i_ = end;
  size_t key = 0;
  std::string name;
  while (next_extended_key(kName, " (ADVANCE, SMOOTH_TIME, EXTRUDER)", &key, &name, st)) {
    if (name == "EXTRUDER") {
      const size_t v = i_;
      while (i_ < n && !is_space(s_[i_]) && s_[i_] != ';' && s_[i_] != '*') ++i_;
      std::string value;
      for (size_t k = v; k < i_; ++k) value.push_back(s_[k]);
      if (value != "extruder") {
        *st = fail(v, "SET_PRESSURE_ADVANCE: unknown EXTRUDER '" + value +
                          "' (the one extruder is 'extruder')");
        return true;
      }
      continue;
    }
    char letter = 0;
    if (name == "ADVANCE")
      letter = 'K';
    else if (name == "SMOOTH_TIME")
      letter = 'S';
    if (letter == 0) {
      *st = fail(key, "SET_PRESSURE_ADVANCE: unknown parameter " + name +
                          " (ADVANCE, SMOOTH_TIME, EXTRUDER)");
      return true;
    }
    if (out_.has(letter)) {
      *st = fail(key, "SET_PRESSURE_ADVANCE: " + name + " given twice");
      return true;
    }
    const NumberScan num = scan_number(s_, i_, true);
    const bool ends =
        num.end >= n || is_space(s_[num.end]) || s_[num.end] == ';' || s_[num.end] == '*';
    if (num.status != NumberScan::Status::kOk || !ends) {
      *st = fail(i_, "SET_PRESSURE_ADVANCE: " + name + " needs a number");
      return true;
    }
    column_[static_cast<size_t>(letter - 'A')] = static_cast<uint32_t>(key);
    out_.set(letter, num.value);
    i_ = num.end;
  }
  return true;  // *st: Ok, or the checksum tail's or a parameter's error
}

Status LineParser::check_checksum_tail(size_t star) const {
  const size_t n = s_.size();
  size_t j = star + 1;
  while (j < n && is_space(s_[j])) ++j;
  const size_t digits = j;
  while (j < n && is_digit(s_[j])) ++j;
  const bool has_digits = j > digits;
  while (j < n && is_space(s_[j])) ++j;
  if (!has_digits || (j < n && s_[j] != ';'))
    return fail(star, "'*' must be followed by a checksum number at the end of the line");
  return Status::Ok();
}

void LineParser::keep_as_text() {
  const char letter = out_.letter;
  const int code = out_.code, subcode = out_.subcode;
  const int64_t line_number = out_.line_number;
  out_.clear();
  out_.letter = letter;
  out_.code = code;
  out_.subcode = subcode;
  out_.line_number = line_number;
  out_.unknown = true;
  assign_valid_utf8(out_.text, argument_text());
}

Status LineParser::validate() const {
  if (out_.unknown) return Status::Ok();
  const CodeRule* rule = find_code_rule(out_.letter, out_.code);
  if (rule == nullptr) return Status::Ok();  // unreachable: unknown is set when no rule
  for (uint32_t mask = out_.parameter_mask(); mask != 0; mask &= mask - 1) {
    const int b = std::countr_zero(mask);
    const char letter = static_cast<char>('A' + b);
    const ParamRule* p = nullptr;
    for (const ParamRule& r : rule->params)
      if (r.letter == letter) p = &r;
    if (p == nullptr) {
      std::string allowed;
      for (const ParamRule& r : rule->params) {
        allowed += allowed.empty() ? "" : " ";
        allowed += r.letter;
      }
      return fail(column_[b], command_name(out_) + " (" + rule->summary + "): parameter " +
                                  letter + " is not allowed" +
                                  (allowed.empty() ? " (it takes none)"
                                                   : " (allowed: " + allowed + ")"));
    }
    Status st = check_parameter(*rule, *p, letter);
    if (!st) return st;
  }
  if (rule->cross == CrossCheck::kArc) {
    const bool centre = out_.has('I') || out_.has('J');
    if (centre && out_.has('R'))
      return fail(column_['R' - 'A'], command_name(out_) + ": give I/J or R, not both");
    if (!centre && !out_.has('R'))
      return fail(command_pos_,
                  command_name(out_) + ": an arc needs I/J (centre offset) or R (radius)");
  }
  return Status::Ok();
}

Status LineParser::check_parameter(const CodeRule& rule, const ParamRule& p, char letter) const {
  const size_t col = column_[letter - 'A'];
  auto what = [&] { return command_name(out_) + " (" + rule.summary + "): " + letter; };
  if (!out_.has_value(letter)) {
    if (p.kind == ParamRule::Kind::kNumber) return fail(col, what() + " needs a number");
    return Status::Ok();
  }
  if (p.kind == ParamRule::Kind::kFlag) return Status::Ok();  // value ignored, as in Marlin
  const double v = out_.get(letter);
  if (!std::isfinite(v)) return fail(col, what() + " must be a finite number");
  const bool below = p.min_exclusive ? !(v > p.min) : v < p.min;
  if (below || v > p.max) {
    std::string bound;
    if (std::isinf(p.max)) bound = std::string(p.min_exclusive ? "> " : ">= ") + fmt(p.min);
    else bound = "between " + fmt(p.min) + " and " + fmt(p.max);
    return fail(col, what() + " must be " + bound + " (got " + fmt(v) + ")");
  }
  if (p.integer && v != std::floor(v))
    return fail(col, what() + " must be a whole number (got " + fmt(v) + ")");
  return Status::Ok();
}

}  // namespace

Status parse_line(std::string_view line, const SourceLocation& where, Command& out) {
  out.clear();
  if (out.where.source != where.source) out.where.source = where.source;
  out.where.line = where.line;
  out.where.column = 0;
  return LineParser(line, where, out).run();
}

Result<Command> parse_line(std::string_view line, const SourceLocation& where) {
  Command c;
  Status st = parse_line(line, where, c);
  if (!st) return st.error();
  return c;
}

}  // namespace feedloop::gcode
