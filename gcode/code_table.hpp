// The G/M codes feedloop knows and what each accepts: which parameter letters, whether a letter
// may be a bare flag ("G28 X"), and the range of its value (Marlin 2.x meanings, see the table in
// code_table.cpp). The parser (gcode/parser.cpp) checks every known command against this table;
// commands not in it parse generically and are marked `unknown`.
#pragma once

#include <cstdint>
#include <span>

namespace feedloop::gcode {

// How one parameter letter of one code is checked.
struct ParamRule {
  enum class Kind : uint8_t {
    kNumber,        // must carry a number: "X10"
    kFlag,          // a bare letter; a number, if given, is ignored by Marlin ("G28 X0" = "G28 X")
    kFlagOrNumber,  // either ("M84 S10" vs "M84 X")
  };
  char letter;
  Kind kind;
  double min;              // inclusive lower bound unless min_exclusive
  double max;              // inclusive upper bound
  bool min_exclusive = false;
  bool integer = false;    // value must be a whole number (tool index, fan index, line number)
};

// Checks across parameters that one letter's rule cannot express.
enum class CrossCheck : uint8_t {
  kNone,
  kArc,  // G2/G3: I/J (centre offset) or R (radius), not both, not neither
};

struct CodeRule {
  char letter;  // 'G' or 'M'
  int code;
  const char* summary;  // what it does, for messages and docs
  std::span<const ParamRule> params;
  CrossCheck cross = CrossCheck::kNone;
};

// The rule for (letter, code), or nullptr for a code the table does not know. Letter uppercase.
// O(1); no allocation.
const CodeRule* find_code_rule(char letter, int code);

// Commands whose argument is free text kept raw in Command::text (M117 message, M23 file name).
bool is_text_command(char letter, int code);

// Every rule, in table order (tests iterate over it).
std::span<const CodeRule> all_code_rules();

}  // namespace feedloop::gcode
