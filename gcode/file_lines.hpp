// Reads a G-code file in fixed 64 KiB chunks through a LineSplitter: the streaming reader that
// batch mode, replay and the tests use for files of any size (memory stays at one chunk plus at
// most one capped line, whatever the file holds).
#pragma once

#include <fcntl.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <string>

#include "core/result.hpp"
#include "gcode/line_splitter.hpp"

namespace feedloop::gcode {

// Calls on_line(const SplitLine&) for every line of the file at `path`, then returns Ok, or an
// Error naming the file when it cannot be opened or read.
template <class F>
Status for_each_file_line(const std::string& path, F&& on_line,
                          size_t max_line_bytes = LineSplitter::kDefaultMaxLineBytes) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return Error{"cannot open G-code file: " + std::string(std::strerror(errno)), {path}};
  LineSplitter splitter(max_line_bytes);
  std::array<char, 64 * 1024> chunk;
  for (;;) {
    const ssize_t n = ::read(fd, chunk.data(), chunk.size());
    if (n < 0) {
      if (errno == EINTR) continue;
      const int err = errno;
      ::close(fd);
      return Error{"cannot read G-code file: " + std::string(std::strerror(err)), {path}};
    }
    if (n == 0) break;
    splitter.feed(std::string_view(chunk.data(), static_cast<size_t>(n)), on_line);
  }
  splitter.finish(on_line);
  ::close(fd);
  return Status::Ok();
}

}  // namespace feedloop::gcode
