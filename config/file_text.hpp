// Reading a config or calibration file whole, with a bound: a printer config is a few kB, and a
// path that is not one (/dev/zero, a disk image) must end in an error, not in memory running out.
#pragma once

#include <cstddef>
#include <string>

#include "core/result.hpp"

namespace feedloop::config {

inline constexpr std::size_t kMaxConfigFileBytes = 16u << 20;  // 16 MiB

// The file's text; `what` names it in errors ("config file", "calibration file").
Result<std::string> read_config_file_text(const std::string& path, const char* what);

}  // namespace feedloop::config
