#include "daemon/job_files.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <filesystem>

#include "core/atomic_file.hpp"
#include "core/utf8.hpp"

namespace feedloop::daemon {

namespace {
constexpr size_t kMaxNameBytes = 255;   // NAME_MAX on Linux file systems
constexpr size_t kMaxPathBytes = 4095;  // PATH_MAX - 1

bool has_gcode_extension(std::string_view name) {
  // The extensions Marlin's SD listing and Moonraker's file manager accept for G-code.
  for (std::string_view ext : {".gcode", ".gco", ".g", ".gc"}) {
    if (name.size() > ext.size()) {
      std::string_view tail = name.substr(name.size() - ext.size());
      bool same = true;
      for (size_t i = 0; i < ext.size(); ++i)
        if (static_cast<char>(std::tolower(static_cast<unsigned char>(tail[i]))) != ext[i])
          same = false;
      if (same) return true;
    }
  }
  return false;
}

std::string errno_text(int err) {
  return std::strerror(err);
}

Result<JobFileInfo> info_of(const std::string& path, std::string_view name) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    const int err = errno;
    if (err == ENOENT) return Error{"no job file named '" + std::string(name) + "'"};
    return Error{"cannot read job file '" + std::string(name) + "': " + errno_text(err)};
  }
  if (!S_ISREG(st.st_mode)) return Error{"'" + std::string(name) + "' is not a regular file"};
  JobFileInfo info;
  info.name = std::string(name);
  info.size_bytes = static_cast<uint64_t>(st.st_size);
  info.modified_unix_s = static_cast<double>(st.st_mtim.tv_sec) + st.st_mtim.tv_nsec * 1e-9;
  return info;
}
}  // namespace

JobFiles::JobFiles(std::string directory, uint64_t max_file_size_bytes)
    : directory_(std::move(directory)), max_size_(max_file_size_bytes) {}

Status JobFiles::open() {
  std::error_code ec;
  std::filesystem::create_directories(directory_, ec);
  if (ec) return Error{"jobs.directory '" + directory_ + "': cannot create it: " + ec.message()};
  if (!std::filesystem::is_directory(directory_, ec))
    return Error{"jobs.directory '" + directory_ + "' is not a directory"};
  ::chmod(directory_.c_str(), 0750);
  return Status::Ok();
}

namespace {
// One path component of `path` at [begin, end): the checks of validate_name; `file` adds the
// G-code extension (a folder needs none). Byte positions in the messages count from the path's
// start.
Status check_component(std::string_view path, size_t begin, size_t end, bool file) {
  const std::string_view name = path.substr(begin, end - begin);
  const std::string what = file ? "file name" : "folder name";
  if (name.empty()) {
    if (file)
      return Error{begin == 0 ? "file name is empty" : "file name is empty (the path ends in '/')"};
    return Error{begin == 0 ? std::string("the path starts with '/' (it is relative to the folder)")
                            : "empty folder name at byte " + std::to_string(begin + 1)};
  }
  if (name.size() > kMaxNameBytes)
    return Error{what + " is " + std::to_string(name.size()) + " bytes long (at most " +
                 std::to_string(kMaxNameBytes) + ")"};
  size_t bad = 0;
  for (size_t i = begin; i < end;) {
    const auto b = static_cast<unsigned char>(path[i]);
    const std::string at = " at byte " + std::to_string(i + 1);
    if (b == 0) return Error{what + " has a NUL byte" + at};
    if (b < 0x20 || b == 0x7f) return Error{what + " has a control character" + at};
    if (b == '/' || b == '\\')
      return Error{what + " has a path separator" + at + " (one name, no folders)"};
    const size_t n = utf8_sequence_length(path, i, &bad);
    if (n == 0) return Error{what + " is not valid UTF-8" + at};
    i += n;
  }
  if (name.front() == '.')
    return Error{what + " starts with '.' (hidden names and '..' are refused)" +
                 (begin > 0 ? " at byte " + std::to_string(begin + 1) : std::string())};
  if (file && !has_gcode_extension(name))
    return Error{"file name must end in .gcode, .gco, .gc or .g"};
  return Status::Ok();
}
}  // namespace

Status JobFiles::validate_name(std::string_view name) {
  return check_component(name, 0, name.size(), true);
}

Status JobFiles::validate_path(std::string_view path) {
  if (path.size() > kMaxPathBytes)
    return Error{"file path is " + std::to_string(path.size()) + " bytes long (at most " +
                 std::to_string(kMaxPathBytes) + ")"};
  size_t begin = 0;
  for (size_t slash; (slash = path.find('/', begin)) != std::string_view::npos; begin = slash + 1)
    if (Status s = check_component(path, begin, slash, false); !s) return s;
  return check_component(path, begin, path.size(), true);
}

std::string JobFiles::path_of(std::string_view name) const {
  return directory_ + "/" + std::string(name);
}

Result<std::vector<JobFileInfo>> JobFiles::list() const {
  std::vector<JobFileInfo> out;
  std::error_code ec;
  std::filesystem::directory_iterator it(directory_, ec);
  if (ec) return Error{"cannot list jobs.directory '" + directory_ + "': " + ec.message()};
  for (const auto& entry : it) {
    const std::string name = entry.path().filename().string();
    if (!validate_name(name)) continue;
    auto info = info_of(entry.path().string(), name);
    if (info) out.push_back(std::move(*info));
  }
  std::sort(out.begin(), out.end(),
            [](const JobFileInfo& a, const JobFileInfo& b) { return a.name < b.name; });
  return out;
}

Result<JobFileInfo> JobFiles::stat(std::string_view name) const {
  if (Status s = validate_path(name); !s) return s.error();
  return info_of(path_of(name), name);
}

Result<JobFileInfo> JobFiles::write(std::string_view name, std::string_view content) {
  if (Status s = validate_name(name); !s) return s.error();
  if (content.size() > max_size_)
    return Error{"file '" + std::string(name) + "' is " + std::to_string(content.size()) +
                 " bytes, above jobs.max_file_size_mb (" + std::to_string(max_size_) + " bytes)"};
  const std::string final_path = path_of(name);
  if (Status s = write_file_atomically(final_path, content, 0640); !s)
    return Error{"job file '" + std::string(name) + "': " + s.error().message};
  return info_of(final_path, name);
}

Status JobFiles::remove(std::string_view name) {
  if (Status s = validate_name(name); !s) return s;
  if (::unlink(path_of(name).c_str()) != 0) {
    const int err = errno;
    if (err == ENOENT) return Error{"no job file named '" + std::string(name) + "'"};
    return Error{"cannot delete job file '" + std::string(name) + "': " + errno_text(err)};
  }
  return Status::Ok();
}

}  // namespace feedloop::daemon
