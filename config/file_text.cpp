// See file_text.hpp.
#include "config/file_text.hpp"

#include <cstring>
#include <utility>

#include "core/bounded_file.hpp"

namespace feedloop::config {

Result<std::string> read_config_file_text(const std::string& path, const char* what) {
  BoundedFile f = read_file_bounded(path, kMaxConfigFileBytes);
  switch (f.status) {
    case BoundedFile::Status::kOk:
      return std::move(f.text);
    case BoundedFile::Status::kTooLarge:
      return Error{std::string(what) + " is larger than " + std::to_string(kMaxConfigFileBytes >> 20) +
                       " MiB: not a printer's YAML",
                   SourceLocation{path, 0, 0}};
    case BoundedFile::Status::kCannotOpen:
    case BoundedFile::Status::kReadError:
      break;
  }
  return Error{std::string("cannot read ") + what + ": " + std::strerror(f.errno_value),
               SourceLocation{path, 0, 0}};
}

}  // namespace feedloop::config
