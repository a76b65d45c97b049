// The job folder: G-code files a print job reads (issue 16). Names are checked before any file
// system call: one path component (no '/', no "." or "..", no leading '.'), no NUL or control
// bytes, valid UTF-8, at most 255 bytes, and an accepted G-code extension; a job may also read a
// file in a subfolder, each folder name checked the same way (validate_path); uploads above
// `max_file_size_bytes` are refused. Uploads are written to a hidden temporary file in the folder
// and renamed into place, so a reader never sees half a file. Not thread-safe: the daemon's I/O
// thread owns it (a web API calls it through the daemon).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "core/result.hpp"

namespace feedloop::daemon {

struct JobFileInfo {
  std::string name;
  uint64_t size_bytes = 0;
  double modified_unix_s = 0.0;
};

class JobFiles {
 public:
  // `directory` is created (0750) by open(); nothing happens at construction.
  JobFiles(std::string directory, uint64_t max_file_size_bytes);

  // Creates the folder when missing and checks it is a directory.
  Status open();
  const std::string& directory() const { return directory_; }
  uint64_t max_file_size_bytes() const { return max_size_; }

  // Ok, or why `name` may not name a job file (the error names the offending byte's position).
  static Status validate_name(std::string_view name);
  // A file in a subfolder, relative to the folder ("parts/cube.gcode", as Moonraker's gcodes
  // paths are): folder names separated by '/', each checked as a name is (no "." or "..", no
  // leading '.', no '\\'), the last a valid file name; at most 4095 bytes. No escape is possible
  // by name. (Symbolic links inside the folder are followed, as Moonraker follows them.)
  static Status validate_path(std::string_view path);

  // Files with an accepted name, sorted by name. Other entries (temporaries, folders) are skipped.
  Result<std::vector<JobFileInfo>> list() const;
  // `name` may be a path into a subfolder (validate_path): a job can print it.
  Result<JobFileInfo> stat(std::string_view name) const;
  // Writes `content` as `name` (replacing a file of that name).
  Result<JobFileInfo> write(std::string_view name, std::string_view content);
  Status remove(std::string_view name);
  // The full path of a valid name or path (validate first).
  std::string path_of(std::string_view name) const;

 private:
  std::string directory_;
  uint64_t max_size_;
};

}  // namespace feedloop::daemon
