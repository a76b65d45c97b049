// Serial transport (Boost.Asio serial_port + termios raw mode): see serial_transport.hpp.
#include "drivers/transport/serial_transport.hpp"

#include <poll.h>     // poll, ppoll
#include <termios.h>  // cfmakeraw, tcsetattr

#include <boost/asio/io_context.hpp>
#include <boost/asio/serial_port.hpp>
#include <boost/asio/write.hpp>
#include <cerrno>
#include <cstring>

namespace feedloop::drivers {

namespace asio = boost::asio;

struct SerialTransport::Impl {
  asio::io_context io;
  asio::serial_port port{io};
  bool up = false;
};

SerialTransport::SerialTransport(std::string path, unsigned baud)
    : impl_(std::make_unique<Impl>()), path_(std::move(path)), baud_(baud) {}

SerialTransport::~SerialTransport() { close(); }

Status SerialTransport::open() {
  close();
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
  impl_->up = true;
  return {};
}

void SerialTransport::close() {
  boost::system::error_code ec;
  if (impl_->port.is_open()) impl_->port.close(ec);
  impl_->up = false;
}

bool SerialTransport::connected() const { return impl_->up; }

Status SerialTransport::write(const uint8_t* data, size_t n) {
  if (!impl_->up) return Error{"serial port " + path_ + " is not open", {}};
  boost::system::error_code ec;
  asio::write(impl_->port, asio::buffer(data, n), ec);
  if (ec) {
    impl_->up = false;
    return Error{"write to " + path_ + " failed: " + ec.message(), {}};
  }
  return {};
}

Result<size_t> SerialTransport::read(uint8_t* buf, size_t cap) {
  if (!impl_->up) return Error{"serial port " + path_ + " is not open", {}};
  pollfd p{impl_->port.native_handle(), POLLIN, 0};
  const int r = ::poll(&p, 1, 0);
  if (r <= 0) return size_t{0};
  if (p.revents & (POLLERR | POLLHUP | POLLNVAL)) {
    if (!(p.revents & POLLIN)) {
      impl_->up = false;
      return Error{"serial port " + path_ + " hung up (device gone)", {}};
    }
  }
  boost::system::error_code ec;
  const size_t n = impl_->port.read_some(asio::buffer(buf, cap), ec);
  if (ec) {
    impl_->up = false;
    return Error{"read from " + path_ + " failed: " + ec.message(), {}};
  }
  return n;
}

void SerialTransport::poll(double /*now_s*/, double max_wait_s) {
  if (!impl_->up || max_wait_s <= 0.0) return;
  pollfd p{impl_->port.native_handle(), POLLIN, 0};
  // ppoll: sub-millisecond waits sleep instead of spinning (a sleeping process is woken
  // promptly by the scheduler; a spinning one competes for the CPU).
  const auto ns = static_cast<long>(max_wait_s * 1e9);
  timespec ts{ns / 1'000'000'000, ns % 1'000'000'000};
  ::ppoll(&p, 1, &ts, nullptr);
}

}  // namespace feedloop::drivers
