// Whole-file text reads and writes for the command-line tools.
#pragma once

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>

#include "core/result.hpp"

namespace feedloop::cli {

// The file's bytes; "" when it cannot be read.
inline std::string read_text_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  if (in) text << in.rdbuf();
  return text.str();
}

// Writes `text` to a temporary file beside `path` and renames it over `path`: a reader (the
// daemon loading a calibration) sees the old file or the new one, never half of one.
inline Status write_text_file(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out << text;
    if (!out.flush()) return Error{"cannot write " + tmp + ": " + std::strerror(errno), {}};
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0)
    return Error{"cannot rename " + tmp + " to " + path + ": " + std::strerror(errno), {}};
  return Status{};
}

}  // namespace feedloop::cli
