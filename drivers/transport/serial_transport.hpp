// Serial transport (USB CDC-ACM MCUs appear as /dev/ttyACM*; feedloop-vmcu offers a
// pseudo-terminal): Boost.Asio opens the port and sets the baud rate, termios raw mode
// (cfmakeraw), 8N1, no flow control, non-blocking. The bytes move on the transport's I/O thread
// (queued_transport.hpp): it writes the queued frames (what the kernel does not take waits for
// POLLOUT; counted as tx_blocked), reads what arrives in chunks stamped with their arrival, and
// sleeps in ppoll() between. A hang-up or an I/O error takes the link down with the reason.
// Owner: the caller's side one thread (the servo thread); the port itself the I/O thread.
#pragma once

#include <memory>
#include <string>

#include "drivers/transport/queued_transport.hpp"

namespace feedloop::drivers {

class SerialTransport final : public QueuedTransport {
 public:
  explicit SerialTransport(std::string path, unsigned baud = 250000, QueuedTransportParams io = serial_io_params());
  ~SerialTransport() override;

  std::string describe() const override { return "serial " + path_; }
  static QueuedTransportParams serial_io_params() {
    QueuedTransportParams p;
    p.thread_name = "fl-io-serial";
    return p;
  }

 protected:
  Status device_open() override;
  void device_close() override;
  void device_io(double max_wait_s) override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string path_;
  unsigned baud_;
  size_t tx_offset_ = 0;  // I/O thread: bytes of the front frame already written
};

}  // namespace feedloop::drivers
