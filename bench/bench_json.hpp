// A benchmark's --json file: every bench writes its figures through this (nlohmann-json).
#pragma once

#include <cstdio>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

namespace feedloop::bench {

// Writes `j` to `path`, two-space indented. Texts that come from outside (file names, a kernel
// string, error messages) may hold bytes that are not UTF-8: replaced, not thrown on. False, with
// a message naming the file on stderr, when it cannot be written.
inline bool write_json(const std::string& path, const nlohmann::json& j) {
  std::ofstream f(path);
  if (f) f << j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
  if (!f) {
    std::fprintf(stderr, "cannot write %s\n", path.c_str());
    return false;
  }
  return true;
}

}  // namespace feedloop::bench
