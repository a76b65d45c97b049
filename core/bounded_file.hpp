// Reading a whole file with a bound on its size: a path that never ends (/dev/zero) or a file far
// beyond what the reader expects ends in an error its caller words, not in memory running out.
// Read in chunks, so a file within the bound costs its size and a chunk.
#pragma once

#include <cstddef>
#include <string>

namespace feedloop {

struct BoundedFile {
  enum class Status { kOk, kCannotOpen, kTooLarge, kReadError };
  Status status = Status::kOk;
  std::string text;     // the whole file when kOk
  int errno_value = 0;  // for kCannotOpen and kReadError
};

BoundedFile read_file_bounded(const std::string& path, std::size_t max_bytes);

}  // namespace feedloop
