// Whole-file text reads and writes for the command-line tools.
#pragma once

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <optional>
#include <string>

#include "config/file_text.hpp"
#include "core/atomic_file.hpp"
#include "core/bounded_file.hpp"
#include "core/result.hpp"

namespace feedloop::cli {

// A file that may not exist yet (a calibration overlay a fit merges into): nullopt when there is
// none; an error when it exists but cannot be read whole (no permission, a directory, a device
// that never ends, over 16 MiB): taking it for empty would write over what it holds.
inline Result<std::optional<std::string>> read_existing_text_file(const std::string& path) {
  BoundedFile f = read_file_bounded(path, config::kMaxConfigFileBytes);
  switch (f.status) {
    case BoundedFile::Status::kOk:
      return std::optional<std::string>(std::move(f.text));
    case BoundedFile::Status::kCannotOpen:
      if (f.errno_value == ENOENT) return std::optional<std::string>();
      break;
    case BoundedFile::Status::kTooLarge:
      return Error{"larger than " + std::to_string(config::kMaxConfigFileBytes >> 20) +
                       " MiB: not a calibration file",
                   {path, 0, 0}};
    case BoundedFile::Status::kReadError:
      break;
  }
  return Error{std::string("cannot read: ") + std::strerror(f.errno_value), {path, 0, 0}};
}

// Writes `text` over `path` atomically (core/atomic_file.hpp): a reader (the daemon loading a
// calibration) sees the old file or the new one, never half of one.
inline Status write_text_file(const std::string& path, const std::string& text) {
  return write_file_atomically(path, text);
}

}  // namespace feedloop::cli
