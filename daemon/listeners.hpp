// The daemon's client channels on the I/O thread: Unix stream sockets (the G-code line socket
// and the JSON API socket) and a pseudo-terminal that looks like a Marlin serial port.
#pragma once

#include <boost/asio.hpp>

#include <cstdint>
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
//
// The slave side never echoes. A host that sets its port to a terminal's defaults (`stty sane`,
// a terminal program, a script that opens the port without making it raw) turns ECHO on, and the
// slave then sends every reply back to the daemon as input: "ok T:22.1 ..." came back as a line,
// was answered with an error, which came back in turn (330 kB of errors in 3 s, the client's
// throttle the only brake). Before each write the daemon turns ECHO and ECHONL off again on its
// own slave descriptor (the host's other settings are left alone) and logs that it did.
class PtyChannel {
 public:
  explicit PtyChannel(boost::asio::io_context& io);
  ~PtyChannel();
  PtyChannel(const PtyChannel&) = delete;  // the session's write guard holds `this`
  PtyChannel& operator=(const PtyChannel&) = delete;
  Status open(const std::string& link_path, SessionFactory on_session);
  void close();
  const std::string& slave_name() const { return slave_name_; }

 private:
  void keep_slave_from_echoing();

  boost::asio::io_context& io_;
  std::string link_path_;
  std::string slave_name_;
  int slave_fd_ = -1;
  std::shared_ptr<ClientSession> session_;
  uint64_t echo_turned_off_ = 0;  // times a host had turned the slave's echo on
};

}  // namespace feedloop::daemon
