// A request body kept in an unnamed temporary file instead of memory: what an upload is read into.
// A stalled or slow upload then holds disk blocks it has actually received, not the whole
// announced Content-Length in RAM (Beast's string body reserves it at the first body byte: 64
// stalled 256 MiB uploads could hold 16 GiB). The file has no name (O_TMPFILE, or mkstemp and an
// unlink at once where the file system lacks it), so nothing is left behind by a crash; the body is
// read back through a read-only mapping (page cache, not the daemon's heap).
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <string_view>

#include "core/result.hpp"

namespace feedloop::web {

class SpooledBody {
 public:
  // A new empty body in `dir` (created when missing; empty: the system's temporary folder).
  static Result<std::unique_ptr<SpooledBody>> create(const std::string& dir);
  ~SpooledBody();
  SpooledBody(const SpooledBody&) = delete;
  SpooledBody& operator=(const SpooledBody&) = delete;

  // Appends bytes; an error (disk full, ...) names the folder and the cause.
  Status append(const char* data, size_t size);
  size_t size() const { return size_; }
  // Every byte appended so far, mapped read-only; valid until the next append or destruction.
  Result<std::string_view> bytes();

 private:
  SpooledBody(int fd, std::string dir) : fd_(fd), dir_(std::move(dir)) {}
  void unmap();

  int fd_ = -1;
  std::string dir_;
  size_t size_ = 0;
  void* map_ = nullptr;
  size_t mapped_ = 0;
};

}  // namespace feedloop::web
