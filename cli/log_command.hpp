// `feedloop log info LOG...` and `feedloop log export LOG... --csv FILE [--rate-hz N]`: the
// flight recorder's offline tools (recorder/log_summary.hpp, recorder/trace_export.hpp).
#pragma once

#include <string>
#include <vector>

namespace feedloop::cli {

// args: everything after "log". Returns the process exit code (0 ok, 1 failure, 2 usage).
int log_command(const std::vector<std::string>& args);

}  // namespace feedloop::cli
