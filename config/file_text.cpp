// See file_text.hpp.
#include "config/file_text.hpp"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <vector>

namespace feedloop::config {

Result<std::string> read_config_file_text(const std::string& path, const char* what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Error{std::string("cannot read ") + what + ": " + std::strerror(errno), SourceLocation{path, 0, 0}};
  std::string text;
  std::vector<char> chunk(64 * 1024);
  while (in) {
    in.read(chunk.data(), static_cast<std::streamsize>(chunk.size()));
    text.append(chunk.data(), static_cast<std::size_t>(in.gcount()));
    if (text.size() > kMaxConfigFileBytes)
      return Error{std::string(what) + " is larger than " + std::to_string(kMaxConfigFileBytes >> 20) +
                       " MiB: not a printer's YAML",
                   SourceLocation{path, 0, 0}};
  }
  if (in.bad()) return Error{std::string("cannot read ") + what + ": " + std::strerror(errno), SourceLocation{path, 0, 0}};
  return text;
}

}  // namespace feedloop::config
