// See bounded_file.hpp.
#include "core/bounded_file.hpp"

#include <cerrno>
#include <fstream>
#include <vector>

namespace feedloop {

BoundedFile read_file_bounded(const std::string& path, std::size_t max_bytes) {
  BoundedFile out;
  errno = 0;
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    out.status = BoundedFile::Status::kCannotOpen;
    out.errno_value = errno;
    return out;
  }
  std::vector<char> chunk(1 << 16);
  while (in) {
    in.read(chunk.data(), static_cast<std::streamsize>(chunk.size()));
    out.text.append(chunk.data(), static_cast<std::size_t>(in.gcount()));
    if (out.text.size() > max_bytes) {
      out.text.clear();
      out.text.shrink_to_fit();
      out.status = BoundedFile::Status::kTooLarge;
      return out;
    }
  }
  if (in.bad()) {
    out.status = BoundedFile::Status::kReadError;
    out.errno_value = errno;
    out.text.clear();
  }
  return out;
}

}  // namespace feedloop
