#include "daemon/runtime_dir.hpp"

#include <sys/stat.h>

#include <cstdio>
#include <filesystem>

namespace feedloop::daemon {

namespace fs = std::filesystem;

namespace {
std::string octal(unsigned mode) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%04o", mode & 07777u);
  return buf;
}
}  // namespace

Status check_directory_safe(const std::string& dir) {
  std::error_code ec;
  fs::path p = fs::absolute(dir, ec);
  if (ec) return Error{"cannot resolve directory " + dir + ": " + ec.message()};
  // The directory and each of its parents: one that anyone may write without the sticky bit lets
  // another user rename what is below it.
  for (fs::path d = p; !d.empty(); d = d.parent_path()) {
    struct stat st {};
    if (::stat(d.c_str(), &st) == 0 && S_ISDIR(st.st_mode) && (st.st_mode & S_IWOTH) != 0 &&
        (st.st_mode & S_ISVTX) == 0)
      return Error{"refusing directory " + d.string() + ": it is writable by every user (mode " +
                   octal(st.st_mode) + ") and has no sticky bit, so another user could plant a socket there; " +
                   "chmod o-w or +t it, or use another runtime directory"};
    if (d == d.parent_path()) break;
  }
  return Status::Ok();
}

Status check_channel_path(const std::string& what, const std::string& path, const std::string& runtime_dir,
                          unsigned mode, std::vector<std::string>* warnings) {
  const fs::path p(path);
  if (p.is_relative())
    warnings->push_back(what + " path '" + path + "' is relative: it depends on the daemon's working directory");
  if (mode != 0 && (mode & ~0660u) != 0)
    warnings->push_back(what + " mode " + octal(mode) + " is wider than 0660: users outside the group can drive the printer");
  std::error_code ec;
  const fs::path abs = fs::weakly_canonical(fs::absolute(p, ec), ec);
  const fs::path root = fs::weakly_canonical(fs::absolute(runtime_dir, ec), ec);
  const std::string a = abs.string(), r = root.string();
  if (runtime_dir.empty() || a.size() <= r.size() || a.compare(0, r.size(), r) != 0 ||
      (r.back() != '/' && a[r.size()] != '/'))
    return Error{what + " path " + path + " is outside the runtime directory " + runtime_dir +
                 " (${RUNTIME_DIR}); sockets belong there"};
  return check_directory_safe(abs.parent_path().string());
}

}  // namespace feedloop::daemon
