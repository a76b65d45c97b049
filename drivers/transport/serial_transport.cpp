// Serial transport (Boost.Asio serial_port + termios raw mode, I/O thread): see serial_transport.hpp.
#include "drivers/transport/serial_transport.hpp"

#include <fcntl.h>    // fcntl, O_NONBLOCK
#include <poll.h>     // ppoll
#include <pthread.h>  // pthread_setname_np, pthread_setschedparam
#include <sched.h>    // SCHED_FIFO
#include <termios.h>  // cfmakeraw, tcsetattr
#include <unistd.h>   // read, write

#include <boost/asio/io_context.hpp>
#include <boost/asio/serial_port.hpp>
#include <algorithm>  // std::max
#include <cerrno>
#include <cstring>  // strerror

namespace feedloop::drivers {

namespace asio = boost::asio;

struct SerialTransport::Impl {
  asio::io_context io;
  asio::serial_port port{io};
};

SerialTransport::SerialTransport(std::string path, unsigned baud, QueuedTransportParams io)
    : QueuedTransport(io), impl_(std::make_unique<Impl>()), path_(std::move(path)), baud_(baud) {}

SerialTransport::~SerialTransport() { shutdown(); }

Status SerialTransport::device_open() {
  boost::system::error_code ec;
  impl_->port.open(path_, ec);
  if (ec) {
    std::string hint = ec == boost::system::errc::permission_denied
                           ? " (permission denied: add the user to the 'dialout' group)"
                           : ec == boost::system::errc::no_such_file_or_directory
                                 ? " (no such device: is the MCU plugged in?)"
                                 : "";
    return Error{"cannot open serial port " + path_ + ": " + ec.message() + hint, {}};
  }
  // Raw mode first (a pty does not care about the baud rate; a real UART does).
  const int fd = impl_->port.native_handle();
  termios tio{};
  if (::tcgetattr(fd, &tio) == 0) {
    ::cfmakeraw(&tio);
    tio.c_cflag |= CLOCAL | CREAD;
    tio.c_cflag &= ~static_cast<tcflag_t>(CRTSCTS);
    tio.c_cc[VMIN] = 0;
    tio.c_cc[VTIME] = 0;
    ::tcsetattr(fd, TCSANOW, &tio);
  }
  impl_->port.set_option(asio::serial_port_base::baud_rate(baud_), ec);  // ignored on a pty
  // The I/O thread never blocks in write() or read(): it waits in ppoll() only.
  const int fl = ::fcntl(fd, F_GETFL);
  if (fl < 0 || ::fcntl(fd, F_SETFL, fl | O_NONBLOCK) != 0) {
    const std::string why = std::strerror(errno);
    impl_->port.close(ec);
    return Error{"cannot make serial port " + path_ + " non-blocking: " + why, {}};
  }
  tx_offset_ = 0;
  fd_ = fd;
  if (has_io_thread()) {  // the writer (its start is part of opening: may allocate)
    writer_stop_.store(false);
    writer_ = std::thread([this] { writer_main(); });
  }
  return {};
}

void SerialTransport::device_close() {
  writer_stop_.store(true, std::memory_order_release);
  if (writer_.joinable()) writer_.join();
  boost::system::error_code ec;
  if (impl_->port.is_open()) impl_->port.close(ec);
  fd_ = -1;
  tx_offset_ = 0;
}

void SerialTransport::writer_main() {
  pthread_setname_np(pthread_self(), "fl-io-ser-tx");
  if (io_params().rt_priority > 0) {
    sched_param sp{};
    sp.sched_priority = io_params().rt_priority;
    pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);  // refused: the default policy
  }
  int64_t last_turn_ns = mono_ns();
  while (!writer_stop_.load(std::memory_order_acquire)) {
    begin_turn(last_turn_ns);
    if (connected() && write_queued(fd_) == TxState::kFailed) continue;  // the I/O thread closes
    sleep_s(io_params().io_period_s);
  }
}

SerialTransport::TxState SerialTransport::write_queued(int fd) {
  while (const TxFrame* f = tx_front()) {
    if (tx_offset_ == 0) tx_departs(f->ticket);
    const ssize_t w = ::write(fd, f->bytes + tx_offset_, f->n - tx_offset_);
    if (w > 0) {
      tx_offset_ += static_cast<size_t>(w);
      if (tx_offset_ >= f->n) {
        tx_pop();
        tx_offset_ = 0;
      }
      continue;
    }
    if (w < 0 && errno == EINTR) continue;
    if (w < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {  // the device does not keep up
      note_tx_blocked();
      return TxState::kBlocked;
    }
    link_failed("write to " + path_ + " failed: " + std::strerror(errno));
    return TxState::kFailed;
  }
  return TxState::kIdle;
}

// Waits up to max_wait_s for input and reads it; a full receive queue stops reading (the bytes
// wait in the kernel) until the caller has taken some.
void SerialTransport::receive(int fd, double max_wait_s) {
  const bool can_receive = !rx_full();
  pollfd p{fd, static_cast<short>(can_receive ? POLLIN : 0), 0};
  const auto ns = static_cast<long>(max_wait_s * 1e9);
  timespec ts{ns / 1'000'000'000, ns % 1'000'000'000};
  if (::ppoll(&p, 1, &ts, nullptr) <= 0) {
    if (!can_receive) (void)rx_claim();  // counts the full queue
    return;
  }
  const bool hung_up = (p.revents & (POLLERR | POLLHUP | POLLNVAL)) != 0;
  if (p.revents & POLLIN) {
    while (uint8_t* chunk = rx_claim()) {
      const ssize_t r = ::read(fd, chunk, kRxChunkBytes);
      if (r > 0) {
        rx_commit(static_cast<size_t>(r), mono_ns());
        continue;
      }
      if (r == 0 && hung_up) break;  // end of file after a hang-up: below
      if (r == 0 || errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) return;  // drained
      link_failed("read from " + path_ + " failed: " + std::strerror(errno));
      return;
    }
  }
  // A hang-up (the other end closed, the device unplugged) once what it sent has been read.
  if (hung_up) link_failed("serial port " + path_ + " hung up (device gone)");
}

void SerialTransport::device_io(double max_wait_s) {
  if (has_io_thread()) {
    // The writer sends; input wakes this thread at once, so it need not turn every 0.5 ms: 5 ms
    // bounds how late it serves the clock fit, a pause or a stop (and halves the idle cost).
    receive(fd_, std::max(max_wait_s, 5e-3));
    return;
  }
  if (write_queued(fd_) == TxState::kFailed) return;
  receive(fd_, max_wait_s);
}

}  // namespace feedloop::drivers
