// Log file names, the append-only file, pruning (see log_files.hpp).
#include "recorder/log_files.hpp"

#include <fcntl.h>   // open
#include <unistd.h>  // write, fdatasync, close

#include <algorithm>
#include <cerrno>
#include <cstdio>   // snprintf
#include <cstring>  // strerror
#include <ctime>    // gmtime_r
#include <filesystem>
#include <system_error>
#include <vector>

#include "recorder/log_format.hpp"  // kLogExtension

namespace feedloop::recorder {

std::string sanitize_print_name(std::string_view name) {
  std::string s;
  for (char c : name) {
    if (s.size() >= 64) break;
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' ||
                    c == '_' || c == '-';
    s.push_back(ok ? c : '_');
  }
  if (s.empty() || s == "." || s == "..") s = "print";
  return s;
}

std::string log_file_name(int64_t start_unix_ms, std::string_view print_name, uint32_t part) {
  const std::time_t secs = static_cast<std::time_t>(start_unix_ms / 1000);
  std::tm tm{};
  gmtime_r(&secs, &tm);
  char stamp[40];
  std::snprintf(stamp, sizeof stamp, "%04d%02d%02d-%02d%02d%02d-%03d", tm.tm_year + 1900, tm.tm_mon + 1, tm.tm_mday,
                tm.tm_hour, tm.tm_min, tm.tm_sec, static_cast<int>(start_unix_ms % 1000));
  char suffix[24];
  std::snprintf(suffix, sizeof suffix, "_p%03u", part);
  return std::string(stamp) + "_" + sanitize_print_name(print_name) + suffix + kLogExtension;
}

int prune_logs(const std::string& directory, int keep_files, const std::string& keep_path) {
  if (keep_files <= 0) return 0;
  namespace fs = std::filesystem;
  std::error_code ec;
  std::vector<fs::path> logs;
  for (fs::directory_iterator it(directory, ec), end; !ec && it != end; it.increment(ec)) {
    if (it->is_regular_file(ec) && it->path().extension() == kLogExtension) logs.push_back(it->path());
  }
  std::sort(logs.begin(), logs.end(), [](const fs::path& a, const fs::path& b) { return a.filename() < b.filename(); });
  int deleted = 0;
  size_t remaining = logs.size();
  for (const fs::path& p : logs) {
    if (remaining <= static_cast<size_t>(keep_files)) break;
    if (fs::equivalent(p, keep_path, ec)) continue;
    if (fs::remove(p, ec)) {
      ++deleted;
      --remaining;
    }
  }
  return deleted;
}

Status LogFile::create(const std::string& path) {
  close();
  fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0640);  // prints are not for every user
  if (fd_ < 0) return Error{std::string("cannot create log file: ") + std::strerror(errno), {path, 0, 0}};
  path_ = path;
  size_ = 0;
  return Status::Ok();
}

Status LogFile::append(const uint8_t* data, size_t size) {
  while (size > 0) {
    const ssize_t n = ::write(fd_, data, size);
    if (n < 0) {
      if (errno == EINTR) continue;
      return Error{std::string("cannot write log file: ") + std::strerror(errno), {path_, 0, 0}};
    }
    data += n;
    size -= static_cast<size_t>(n);
    size_ += static_cast<uint64_t>(n);
  }
  return Status::Ok();
}

Status LogFile::sync() {
  if (fd_ >= 0 && ::fdatasync(fd_) != 0)
    return Error{std::string("cannot sync log file: ") + std::strerror(errno), {path_, 0, 0}};
  return Status::Ok();
}

void LogFile::close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

}  // namespace feedloop::recorder
