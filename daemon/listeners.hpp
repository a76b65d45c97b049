// The daemon's client channels on the I/O thread: Unix stream sockets (the G-code line socket
// and the JSON API socket) and a pseudo-terminal that looks like a Marlin serial port.
#pragma once

#include <boost/asio.hpp>

#include <functional>
#include <memory>
#include <string>

#include "core/result.hpp"
#include "daemon/client_session.hpp"

namespace feedloop::daemon {

using SessionFactory = std::function<void(std::shared_ptr<ClientSession>)>;

// Listens on a Unix socket path (removing a stale socket file first), chmod `mode`, and hands
// every accepted connection to `on_session` as a started-later ClientSession.
class UnixListener {
 public:
  UnixListener(boost::asio::io_context& io, std::string name_prefix);
  Status listen(const std::string& path, unsigned mode, SessionFactory on_session);
  void close();
  const std::string& path() const { return path_; }

 private:
  void accept_next();

  std::string prefix_;
  std::string path_;
  boost::asio::local::stream_protocol::acceptor acceptor_;
  SessionFactory on_session_;
  uint64_t next_id_ = 1;
};

// A pseudo-terminal whose slave side is published as a symlink (e.g. /run/feedloop/ttyFEEDLOOP)
// so serial hosts (Printrun's pronsole, OctoPrint) can open it like a USB printer. The daemon
// keeps its own slave descriptor open so a host closing the port is not an error; each
// (re)opening host speaks to the same session.
class PtyChannel {
 public:
  explicit PtyChannel(boost::asio::io_context& io);
  ~PtyChannel();
  Status open(const std::string& link_path, SessionFactory on_session);
  void close();
  const std::string& slave_name() const { return slave_name_; }

 private:
  boost::asio::io_context& io_;
  std::string link_path_;
  std::string slave_name_;
  int slave_fd_ = -1;
  std::shared_ptr<ClientSession> session_;
};

}  // namespace feedloop::daemon
