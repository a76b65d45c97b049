// Serial transport with Boost.Asio (USB CDC-ACM MCUs appear as /dev/ttyACM*; feedloop-vmcu
// offers a pseudo-terminal): raw mode (termios cfmakeraw), 8N1, no flow control. Writes block
// until the frame is handed to the kernel; reads never block (poll() waits with a timeout).
// Owner: the I/O thread.
#pragma once

#include <memory>
#include <string>

#include "drivers/transport.hpp"

namespace feedloop::drivers {

class SerialTransport final : public Transport {
 public:
  explicit SerialTransport(std::string path, unsigned baud = 250000);
  ~SerialTransport() override;
  SerialTransport(const SerialTransport&) = delete;
  SerialTransport& operator=(const SerialTransport&) = delete;

  Status open() override;
  void close() override;
  bool connected() const override;
  Status write(const uint8_t* data, size_t n) override;
  Result<size_t> read(uint8_t* buf, size_t cap) override;
  void poll(double now_s, double max_wait_s) override;
  std::string describe() const override { return "serial " + path_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string path_;
  unsigned baud_;
};

}  // namespace feedloop::drivers
