#include "web/spooled_body.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <system_error>

namespace feedloop::web {

namespace {
std::string cause() { return std::strerror(errno); }
}  // namespace

Result<std::unique_ptr<SpooledBody>> SpooledBody::create(const std::string& dir_in) {
  std::error_code ec;
  const std::string dir =
      dir_in.empty() ? std::filesystem::temp_directory_path(ec).string() : dir_in;
  if (dir.empty()) return Error{"upload: no temporary folder: " + ec.message()};
  std::filesystem::create_directories(dir, ec);
  int fd = ::open(dir.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
  if (fd < 0 && (errno == EOPNOTSUPP || errno == EISDIR || errno == EINVAL)) {
    // A file system without O_TMPFILE: a named file, unlinked at once.
    std::string name = dir + "/.upload-XXXXXX";
    fd = ::mkostemp(name.data(), O_CLOEXEC);
    if (fd >= 0) ::unlink(name.c_str());
  }
  if (fd < 0) return Error{"upload: cannot create a temporary file in " + dir + ": " + cause()};
  return std::unique_ptr<SpooledBody>(new SpooledBody(fd, dir));
}

SpooledBody::~SpooledBody() {
  unmap();
  if (fd_ >= 0) ::close(fd_);
}

void SpooledBody::unmap() {
  if (map_ != nullptr) ::munmap(map_, mapped_);
  map_ = nullptr;
  mapped_ = 0;
}

Status SpooledBody::append(const char* data, size_t size) {
  unmap();
  while (size > 0) {
    const ssize_t n = ::write(fd_, data, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return Error{"upload: cannot write the temporary file in " + dir_ + ": " + cause()};
    data += n;
    size -= static_cast<size_t>(n);
    size_ += static_cast<size_t>(n);
  }
  return Status::Ok();
}

Result<std::string_view> SpooledBody::bytes() {
  if (size_ == 0) return std::string_view{};
  if (map_ == nullptr) {
    void* m = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd_, 0);
    if (m == MAP_FAILED) return Error{"upload: cannot read the temporary file back: " + cause()};
    map_ = m;
    mapped_ = size_;
  }
  return std::string_view(static_cast<const char*>(map_), mapped_);
}

}  // namespace feedloop::web
