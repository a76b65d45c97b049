// One interface for every link to an MCU (DESIGN.md data flow: usb | serial | mock); the config
// chooses. A transport moves whole frames (the host writes one frame per write()) and bytes back;
// it knows nothing about their content. Non-blocking: read() returns what has arrived.
// Owner: the I/O thread (or the batch-mode pipeline thread).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "core/result.hpp"

namespace feedloop::drivers {

class Transport {
 public:
  virtual ~Transport() = default;
  // Opens (or re-opens after a disconnect). Errors say which device and what to do.
  virtual Status open() = 0;
  virtual void close() = 0;
  virtual bool connected() const = 0;
  // Writes one frame. An error means the link is down (connected() turns false).
  virtual Status write(const uint8_t* data, size_t n) = 0;
  // Copies up to cap received bytes into buf; 0 when nothing is there. Error: link down.
  virtual Result<size_t> read(uint8_t* buf, size_t cap) = 0;
  // Lets time pass for in-process transports (the mock runs its virtual MCU up to now_s);
  // real transports may wait up to max_wait_s for input to arrive.
  virtual void poll(double now_s, double max_wait_s) = 0;
  // "serial /dev/ttyACM0", "usb 1d50:614e serial 1234", "mock x"...
  virtual std::string describe() const = 0;
};

}  // namespace feedloop::drivers
