// Serial transport (USB CDC-ACM MCUs appear as /dev/ttyACM*; feedloop-vmcu offers a
// pseudo-terminal): Boost.Asio opens the port and sets the baud rate, termios raw mode
// (cfmakeraw), 8N1, no flow control, non-blocking. The bytes move on two device-side threads
// (queued_transport.hpp): the I/O thread reads what arrives, in chunks stamped with their
// arrival, sleeping in ppoll() between; a writer thread writes the queued frames (what the
// kernel does not take is retried after io_period_s, counted as tx_blocked) and sleeps between.
// Two threads, because on a tty even a non-blocking poll() or read() waits for the kernel's
// worker that moves received bytes into the line discipline (n_tty_poll/n_tty_read call
// tty_buffer_flush_work): on a loaded machine that worker ran up to 1.5 s late and held the
// frames to the device back with it. The writer never polls or reads. A hang-up or an I/O error
// takes the link down with the reason.
// Owner: the caller's side one thread (the servo thread); the port the two device-side threads.
#pragma once

#include <atomic>
#include <memory>
#include <string>
#include <thread>

#include "drivers/transport/queued_transport.hpp"

namespace feedloop::drivers {

class SerialTransport final : public QueuedTransport {
 public:
  explicit SerialTransport(std::string path, unsigned baud = 250000, QueuedTransportParams io = serial_io_params());
  ~SerialTransport() override;

  std::string describe() const override { return "serial " + path_; }
  double io_thread_cpu_s() override { return QueuedTransport::io_thread_cpu_s() + thread_cpu_s(writer_); }
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
  enum class TxState { kIdle, kBlocked, kFailed };
  TxState write_queued(int fd);  // every queued frame the kernel takes now
  void receive(int fd, double max_wait_s);
  void writer_main();

  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string path_;
  unsigned baud_;
  int fd_ = -1;             // while open
  size_t tx_offset_ = 0;    // the writer: bytes of the front frame already written
  std::thread writer_;
  std::atomic<bool> writer_stop_{false};
};

}  // namespace feedloop::drivers
