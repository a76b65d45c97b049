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
#include <type_traits>

#include "core/result.hpp"
#include "gcode/file_kind.hpp"
#include "gcode/line_splitter.hpp"

namespace feedloop::gcode {

// Calls on_line(const SplitLine&) for every line of the file at `path`, and on_read(size_t bytes)
// after each chunk read (when it returns a bool, false stops the reading there), then returns Ok,
// or an Error naming the file when it cannot be opened or read (a directory: "Is a directory").
// Pipes and FIFOs are read to their end like files. A compressed file, an archive or binary
// G-code (gcode/file_kind.hpp) is refused before any of its lines: an Error saying what it is.
template <class F, class R>
Status for_each_file_line_reporting(const std::string& path, F&& on_line, R&& on_read,
                                    size_t max_line_bytes = LineSplitter::kDefaultMaxLineBytes) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return Error{"cannot open G-code file: " + std::string(std::strerror(errno)), {path}};
  LineSplitter splitter(max_line_bytes);
  std::array<char, 64 * 1024> chunk;
  bool first = true;
  for (;;) {
    const ssize_t n = ::read(fd, chunk.data(), chunk.size());
    if (n < 0) {
      if (errno == EINTR) continue;
      const int err = errno;
      ::close(fd);
      return Error{"cannot read G-code file: " + std::string(std::strerror(err)), {path}};
    }
    if (n == 0) break;
    if (first) {
      first = false;
      if (auto kind = non_gcode_file_kind(std::string_view(chunk.data(), static_cast<size_t>(n)))) {
        ::close(fd);
        return Error{*kind, {path}};
      }
    }
    splitter.feed(std::string_view(chunk.data(), static_cast<size_t>(n)), on_line);
    if constexpr (std::is_same_v<std::invoke_result_t<R&, size_t>, bool>) {
      if (!on_read(static_cast<size_t>(n))) break;
    } else {
      on_read(static_cast<size_t>(n));
    }
  }
  splitter.finish(on_line);
  ::close(fd);
  return Status::Ok();
}

// The same without the byte count.
template <class F>
Status for_each_file_line(const std::string& path, F&& on_line,
                          size_t max_line_bytes = LineSplitter::kDefaultMaxLineBytes) {
  return for_each_file_line_reporting(
      path, on_line, [](size_t) {}, max_line_bytes);
}

}  // namespace feedloop::gcode
