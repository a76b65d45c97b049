// One line of G-code text -> one Command (gcode/command.hpp), or an Error with the column of the
// offending word. The dialect (PrusaSlicer, Cura, Slic3r, Marlin hosts) is described in
// gcode/README.md; in short:
//   - comments: ';' to the end of the line, '(' ... ')' inline; case-insensitive letters;
//     whitespace (space, tab, CR) between words is optional ("G1X10E5" == "G1 X10 E5");
//   - numbers: optional sign, digits with an optional '.', e.g. "-.8", "+5", "12.";
//   - exponents: "1e-05", "2.5e+3" are accepted only when the 'e' is lowercase, is followed by an
//     explicit sign and a digit, and the word starts after whitespace. Everything else with an
//     E is the E parameter: "G1 X10 E5", "G1X10E5", "G1 X10E-5" and "g1x10e-5" all mean X10 and
//     E5 / E-5, as Marlin reads them;
//   - an N word at the start is the line number; "*<digits>" ends the command (the host protocol,
//     gcode/host_protocol.hpp, verifies the checksum; the parser only skips it);
//   - free-text commands (M117, M118, M23, M28, M30, M32, M928) keep their argument raw in `text`;
//   - known codes (gcode/code_table.hpp) are validated: allowed letters, flags vs numbers,
//     ranges, whole numbers, G2/G3 I/J-or-R. Unknown codes parse generically (or keep their
//     argument as text when it is not G-code words) and come back with `unknown = true`.
// A line that fails returns an Error and nothing of it may be executed.
#pragma once

#include <string_view>

#include "core/result.hpp"
#include "gcode/command.hpp"

namespace feedloop::gcode {

// Parses `line` (without its newline). `where` names the source and line; the column of an
// Error is filled in here (1-based byte column).
Result<Command> parse_line(std::string_view line, const SourceLocation& where);

// The same, reusing `out` (its string storage is kept): no heap allocation for ordinary lines
// once `out.where.source` has its capacity. On error `out` is left cleared.
Status parse_line(std::string_view line, const SourceLocation& where, Command& out);

}  // namespace feedloop::gcode
