// See atomic_file.hpp.
#include "core/atomic_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

namespace feedloop {

Status write_file_atomically(const std::string& path, std::string_view data, mode_t mode) {
  const size_t slash = path.find_last_of('/');
  const std::string dir = slash == std::string::npos ? "." : (slash == 0 ? "/" : path.substr(0, slash));
  std::string tmp = (slash == std::string::npos ? std::string() : path.substr(0, slash + 1)) + ".tmp-XXXXXX";
  const int fd = ::mkstemp(tmp.data());
  if (fd < 0) return Error{"cannot create a file in " + dir + ": " + std::strerror(errno)};
  auto fail = [&](const std::string& what, int err) {
    ::unlink(tmp.c_str());
    return Error{what + path + ": " + std::strerror(err)};
  };
  ::fchmod(fd, mode);
  for (size_t off = 0; off < data.size();) {
    const ssize_t n = ::write(fd, data.data() + off, data.size() - off);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = n < 0 ? errno : EIO;
      ::close(fd);
      return fail("cannot write ", err);
    }
    off += static_cast<size_t>(n);
  }
  if (::fsync(fd) != 0) {
    const int err = errno;
    ::close(fd);
    return fail("cannot write ", err);
  }
  if (::close(fd) != 0) return fail("cannot write ", errno);
  if (std::rename(tmp.c_str(), path.c_str()) != 0) return fail("cannot rename over ", errno);
  return Status::Ok();
}

}  // namespace feedloop
