// Files of the flight recorder on disk: names (one file per print and rotation part, sorting
// oldest first), the append-only file with its explicit fdatasync, and pruning beyond keep_files.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "core/result.hpp"

namespace feedloop::recorder {

// "<stamp>_<name>_p<part>.flrec", stamp = UTC "YYYYmmdd-HHMMSS-mmm" of the print start; the name
// keeps [A-Za-z0-9._-] (others become '_', at most 64 characters, empty -> "print").
std::string log_file_name(int64_t start_unix_ms, std::string_view print_name, uint32_t part);
std::string sanitize_print_name(std::string_view name);

// Deletes the oldest *.flrec files of `directory` (by name: the stamp sorts them) until at most
// `keep_files` remain, never `keep_path`. keep_files <= 0 keeps everything. Returns how many it
// deleted (problems are ignored: a file that cannot be deleted stays).
int prune_logs(const std::string& directory, int keep_files, const std::string& keep_path);

// An append-only file descriptor.
class LogFile {
 public:
  LogFile() = default;
  ~LogFile() { close(); }
  LogFile(const LogFile&) = delete;
  LogFile& operator=(const LogFile&) = delete;

  Status create(const std::string& path);  // fails if the file exists
  Status append(const uint8_t* data, size_t size);
  Status sync();                            // fdatasync
  void close();
  bool is_open() const { return fd_ >= 0; }
  const std::string& path() const { return path_; }
  uint64_t size() const { return size_; }

 private:
  int fd_ = -1;
  std::string path_;
  uint64_t size_ = 0;
};

}  // namespace feedloop::recorder
