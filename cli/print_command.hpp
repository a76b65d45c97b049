// `feedloop print FILE`: streams a G-code file to a running feedloopd over its Unix socket with
// the Marlin host protocol (line numbers, checksums, a window of lines in flight), shows
// progress on a terminal, and prints a summary with the daemon's own figures at the end.
#pragma once

#include <string>
#include <vector>

namespace feedloop::cli {

int print_command(const std::vector<std::string>& args);

}  // namespace feedloop::cli
