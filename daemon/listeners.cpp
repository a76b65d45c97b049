#include "daemon/listeners.hpp"

#include <fcntl.h>     // open
#include <pty.h>       // openpty
#include <sys/socket.h>  // SO_PEERCRED
#include <sys/stat.h>  // chmod
#include <termios.h>   // cfmakeraw
#include <unistd.h>    // unlink, symlink, close

#include <cerrno>
#include <cstring>  // strerror
#include <filesystem>

#include <spdlog/spdlog.h>

namespace feedloop::daemon {

namespace asio = boost::asio;
using local_stream = asio::local::stream_protocol;

namespace {
// Creates the directory that will hold `path` (a runtime directory may not exist yet).
Status ensure_parent_dir(const std::string& path) {
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  if (parent.empty()) return Status::Ok();
  std::error_code ec;
  std::filesystem::create_directories(parent, ec);
  if (ec) return Error{"cannot create directory " + parent.string() + ": " + ec.message()};
  return Status::Ok();
}
}  // namespace

UnixListener::UnixListener(asio::io_context& io, std::string name_prefix)
    : prefix_(std::move(name_prefix)), acceptor_(io) {}

Status UnixListener::listen(const std::string& path, unsigned mode, SessionFactory on_session) {
  if (path.empty()) return Error{"socket path is empty"};
  if (path.size() >= sizeof(sockaddr_un::sun_path))
    return Error{"socket path is too long (max " + std::to_string(sizeof(sockaddr_un::sun_path) - 1) +
                 " bytes): " + path};
  if (Status s = ensure_parent_dir(path); !s) return s;
  struct stat st {};
  if (::lstat(path.c_str(), &st) == 0) {
    if (!S_ISSOCK(st.st_mode))
      return Error{"refusing to replace " + path + ": it exists and is not a socket"};
    ::unlink(path.c_str());  // a stale socket from a previous run
  }
  boost::system::error_code ec;
  acceptor_.open(local_stream(), ec);
  if (!ec) acceptor_.bind(local_stream::endpoint(path), ec);
  if (!ec) acceptor_.listen(asio::socket_base::max_listen_connections, ec);
  if (ec) return Error{"cannot listen on " + path + ": " + ec.message()};
  if (::chmod(path.c_str(), mode) != 0)
    return Error{"cannot chmod " + path + ": " + std::strerror(errno)};
  path_ = path;
  on_session_ = std::move(on_session);
  accept_next();
  return Status::Ok();
}

void UnixListener::accept_next() {
  acceptor_.async_accept([this](const boost::system::error_code& ec, local_stream::socket sock) {
    if (ec) {
      if (ec == asio::error::operation_aborted) return;
      accept_next();
      return;
    }
    const uint64_t id = next_id_++;
    // Who connected (SO_PEERCRED): every client in the log with its user and process.
    ucred cred{};
    socklen_t len = sizeof cred;
    if (::getsockopt(sock.native_handle(), SOL_SOCKET, SO_PEERCRED, &cred, &len) == 0)
      spdlog::info("{}#{} connected: uid {} gid {} pid {}", prefix_, id, cred.uid, cred.gid, cred.pid);
    else
      spdlog::info("{}#{} connected: peer unknown ({})", prefix_, id, std::strerror(errno));
    on_session_(std::make_shared<StreamSession<local_stream::socket>>(
        id, prefix_ + "#" + std::to_string(id), std::move(sock)));
    accept_next();
  });
}

void UnixListener::close() {
  boost::system::error_code ignored;
  acceptor_.close(ignored);
  if (!path_.empty()) ::unlink(path_.c_str());
  path_.clear();
}

PtyChannel::PtyChannel(asio::io_context& io) : io_(io) {}
PtyChannel::~PtyChannel() { close(); }

Status PtyChannel::open(const std::string& link_path, SessionFactory on_session) {
  int master = -1;
  char name[128] = {};
  if (::openpty(&master, &slave_fd_, name, nullptr, nullptr) != 0)
    return Error{std::string("cannot open a pseudo-terminal: ") + std::strerror(errno)};
  // Raw mode on the slave: no echo, no line editing, no CR/LF translation.
  termios tio{};
  ::tcgetattr(slave_fd_, &tio);
  ::cfmakeraw(&tio);
  ::tcsetattr(slave_fd_, TCSANOW, &tio);
  ::fcntl(master, F_SETFL, ::fcntl(master, F_GETFL) | O_NONBLOCK);
  slave_name_ = name;
  if (!link_path.empty()) {
    if (Status s = ensure_parent_dir(link_path); !s) {
      ::close(master);
      return s;
    }
    struct stat st {};
    if (::lstat(link_path.c_str(), &st) == 0) {
      if (!S_ISLNK(st.st_mode)) {
        ::close(master);
        return Error{"refusing to replace " + link_path + ": it exists and is not a symlink"};
      }
      ::unlink(link_path.c_str());
    }
    if (::symlink(slave_name_.c_str(), link_path.c_str()) != 0) {
      ::close(master);
      return Error{"cannot create symlink " + link_path + " -> " + slave_name_ + ": " +
                   std::strerror(errno)};
    }
    link_path_ = link_path;
  }
  session_ = std::make_shared<StreamSession<asio::posix::stream_descriptor>>(
      0, "pty:" + slave_name_, asio::posix::stream_descriptor(io_, master));
  session_->set_before_write([this] { keep_slave_from_echoing(); });
  on_session(session_);
  return Status::Ok();
}

void PtyChannel::keep_slave_from_echoing() {
  termios tio{};
  if (slave_fd_ < 0 || ::tcgetattr(slave_fd_, &tio) != 0) return;
  if ((tio.c_lflag & (ECHO | ECHONL)) == 0) return;
  tio.c_lflag &= ~static_cast<tcflag_t>(ECHO | ECHONL);
  ::tcsetattr(slave_fd_, TCSANOW, &tio);
  // Once, then every 100th time: a host that sets its port up on each open is not an emergency.
  if (echo_turned_off_++ % 100 == 0)
    spdlog::warn(
        "pty {}: a host turned the port's echo on (a terminal's defaults); turned it off again, "
        "or the port would send every reply back as a command (times: {})",
        slave_name_, echo_turned_off_);
}

void PtyChannel::close() {
  if (session_) session_->close();
  session_.reset();
  if (slave_fd_ >= 0) ::close(slave_fd_);
  slave_fd_ = -1;
  if (!link_path_.empty()) ::unlink(link_path_.c_str());
  link_path_.clear();
}

}  // namespace feedloop::daemon
