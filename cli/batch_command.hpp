// `feedloop batch FILE [--config CFG] [--json OUT]`: the whole pipeline in virtual time against
// an ideal plant; prints a summary (lines, moves, print time, steps per axis, max step rate,
// bytes on the wire, warnings).
#pragma once

#include <string>
#include <vector>

namespace feedloop::cli {

int batch_command(const std::vector<std::string>& args);

}  // namespace feedloop::cli
