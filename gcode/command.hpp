// One parsed G-code line: the contract between the parser (gcode/parser) and everything that
// executes commands (planner/interpreter, daemon dispatch). Plain data; cheap to copy except for
// `text`, which only message commands (M117, M118, M23...) fill.
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "core/result.hpp"

namespace feedloop::gcode {

// Object labels (Klipper's EXCLUDE_OBJECT family, gcode/parser.cpp): M486 with one of these
// subcodes, the object's name in `text`. The parser gives them for the Klipper forms and for
// Marlin's M486 T/S/P/C, the index as the name (a literal "M486.2" is an unknown command), and
// kObjectName for the name PrusaSlicer gives an indexed object (M486 A<name>: the current
// object's; RepRapFirmware's M486 S<i> A"name": object i's, which starts, the index in S).
enum ObjectLabelForm : int {
  kObjectDefine = 1,
  kObjectStart = 2,
  kObjectEnd = 3,
  kObjectExclude = 4,
  kObjectName = 5
};

struct Command {
  char letter = 0;    // 'G', 'M' or 'T'; 0 for a line with no command (blank, comment only)
  int code = -1;      // 1 for G1, 104 for M104, 0 for T0
  int subcode = -1;   // 1 for G29.1; -1 when absent
  int64_t line_number = -1;  // the N word, -1 when absent
  std::string text;   // free text argument (M117 message, M23 file name), unparsed
  SourceLocation where;      // source name and line of the input this came from
  // Parsed fine, but not one of the codes gcode/code_table.cpp validates: the caller decides
  // whether it can execute it and otherwise warns ("unknown command" is not a failure).
  bool unknown = false;

  bool is(char l, int c) const { return letter == l && code == c; }
  bool empty() const { return letter == 0; }

  // Parameters A..Z (the command letter itself is not a parameter). A parameter is either a
  // word with a number ("X10") or a bare flag ("G28 X", "M84 E"): has() is true for both,
  // has_value() only for the first; get() returns `fallback` for a flag.
  bool has(char p) const { return (mask_ >> index(p)) & 1u; }
  bool has_value(char p) const { return (value_mask_ >> index(p)) & 1u; }
  double get(char p, double fallback = 0.0) const {
    return has_value(p) ? values_[index(p)] : fallback;
  }
  void set(char p, double v) {
    values_[index(p)] = v;
    mask_ |= 1u << index(p);
    value_mask_ |= 1u << index(p);
  }
  void set_flag(char p) { mask_ |= 1u << index(p); }
  bool has_any_parameter() const { return mask_ != 0; }
  uint32_t parameter_mask() const { return mask_; }  // bit i = letter 'A' + i present

  // Back to an empty command, keeping `text`'s and `where.source`'s storage (no allocation when
  // a parser reuses one Command for many lines).
  void clear() {
    letter = 0;
    code = -1;
    subcode = -1;
    line_number = -1;
    text.clear();
    unknown = false;
    mask_ = 0;
    value_mask_ = 0;
  }

 private:
  static int index(char p) { return (p >= 'a' && p <= 'z') ? p - 'a' : p - 'A'; }
  uint32_t mask_ = 0;
  uint32_t value_mask_ = 0;
  std::array<double, 26> values_{};
};

}  // namespace feedloop::gcode
