// Test helper: a blocking line client for Unix sockets and pseudo-terminals, with timeouts.
#pragma once

#include <fcntl.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <termios.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <optional>
#include <string>
#include <thread>

namespace feedloop::testing {

class LineClient {
 public:
  LineClient() = default;
  LineClient(const LineClient&) = delete;
  LineClient& operator=(const LineClient&) = delete;
  ~LineClient() { close(); }

  bool connect_unix(const std::string& path, int attempts = 50) {
    for (int i = 0; i < attempts; ++i) {
      fd_ = ::socket(AF_UNIX, SOCK_STREAM, 0);
      sockaddr_un addr{};
      addr.sun_family = AF_UNIX;
      std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", path.c_str());
      if (::connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0) return true;
      ::close(fd_);
      fd_ = -1;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return false;
  }
  bool open_tty(const std::string& path) {
    fd_ = ::open(path.c_str(), O_RDWR | O_NOCTTY);
    if (fd_ < 0) return false;
    termios tio{};
    ::tcgetattr(fd_, &tio);
    ::cfmakeraw(&tio);
    ::tcsetattr(fd_, TCSANOW, &tio);
    return true;
  }
  // The port set up as a terminal's defaults would (`stty sane`): echo and line editing on.
  bool set_terminal_defaults() {
    termios tio{};
    if (::tcgetattr(fd_, &tio) != 0) return false;
    tio.c_lflag |= ECHO | ECHOE | ECHOK | ICANON | ISIG;
    tio.c_iflag |= ICRNL;
    tio.c_oflag |= OPOST | ONLCR;
    return ::tcsetattr(fd_, TCSANOW, &tio) == 0;
  }
  bool echoes() const {
    termios tio{};
    return ::tcgetattr(fd_, &tio) == 0 && (tio.c_lflag & ECHO) != 0;
  }
  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  bool send(const std::string& text) {
    size_t off = 0;
    while (off < text.size()) {
      const ssize_t n = ::write(fd_, text.data() + off, text.size() - off);
      if (n <= 0) return false;
      off += static_cast<size_t>(n);
    }
    return true;
  }
  bool send_line(const std::string& line) { return send(line + "\n"); }

  // The next line (without '\n'), or nullopt on timeout / end of stream.
  std::optional<std::string> read_line(int timeout_ms = 3000) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
    for (;;) {
      const size_t nl = buf_.find('\n');
      if (nl != std::string::npos) {
        std::string line = buf_.substr(0, nl);
        buf_.erase(0, nl + 1);
        if (!line.empty() && line.back() == '\r') line.pop_back();
        return line;
      }
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
          deadline - std::chrono::steady_clock::now()).count();
      if (left <= 0) return std::nullopt;
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, static_cast<int>(left)) <= 0) return std::nullopt;
      char tmp[4096];
      const ssize_t n = ::read(fd_, tmp, sizeof tmp);
      if (n <= 0) return std::nullopt;
      buf_.append(tmp, static_cast<size_t>(n));
    }
  }
  // Reads lines until one starts with `prefix`; returns it (or nullopt on timeout).
  std::optional<std::string> read_until(const std::string& prefix, int timeout_ms = 5000,
                                        std::string* skipped = nullptr) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
    for (;;) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
          deadline - std::chrono::steady_clock::now()).count();
      if (left <= 0) return std::nullopt;
      auto line = read_line(static_cast<int>(left));
      if (!line) return std::nullopt;
      if (line->rfind(prefix, 0) == 0) return line;
      if (skipped) *skipped += *line + "\n";
    }
  }
  int fd() const { return fd_; }

 private:
  int fd_ = -1;
  std::string buf_;
};

// "N<n> <cmd>*<checksum>" as a Marlin host sends it.
inline std::string numbered(int n, const std::string& cmd) {
  std::string s = "N" + std::to_string(n) + " " + cmd;
  unsigned c = 0;
  for (char ch : s) c ^= static_cast<unsigned char>(ch);
  return s + "*" + std::to_string(c);
}

}  // namespace feedloop::testing
