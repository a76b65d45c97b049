// One connected client on any line-based channel (Unix socket, pty, JSON API socket).
// Lives on the I/O thread. Outgoing lines go through a bounded queue: a client that does not
// read its replies is disconnected rather than allowed to grow memory or stall anything.
#pragma once

#include <boost/asio.hpp>

#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <string>
#include <string_view>

#include "gcode/line_splitter.hpp"

namespace feedloop::daemon {

class ClientSession : public std::enable_shared_from_this<ClientSession> {
 public:
  // Receives each non-empty input line (without its line ending); a line over kMaxLineBytes
  // arrives once as too_long with empty text.
  using LineHandler = std::function<void(ClientSession&, std::string_view line, bool too_long)>;
  using CloseHandler = std::function<void(ClientSession&)>;

  ClientSession(uint64_t id, std::string name) : id_(id), name_(std::move(name)) {}
  virtual ~ClientSession() = default;

  uint64_t id() const { return id_; }
  const std::string& name() const { return name_; }
  bool closed() const { return closed_; }

  void set_handlers(LineHandler on_line, CloseHandler on_close) {
    on_line_ = std::move(on_line);
    on_close_ = std::move(on_close);
  }

  // Queues `line` plus '\n'. Returns false (and closes the session) when the client has more
  // than max_pending_bytes unread. `droppable` lines (status notifications) are skipped instead
  // when the queue is over half full.
  bool send_line(std::string_view line, bool droppable = false);
  uint64_t dropped_lines() const { return dropped_lines_; }

  // Reading stops while paused (backpressure: the machine's queue is full).
  void pause_reading() { paused_ = true; }
  void resume_reading();
  bool paused() const { return paused_; }

  virtual void start() = 0;
  void close();

  static constexpr size_t kMaxPendingBytes = 1 << 20;
  static constexpr size_t kMaxLineBytes = 256 * 1024;

 protected:
  virtual void do_write(const std::string& data) = 0;  // one async write of `data`
  virtual void do_close() = 0;
  virtual void do_read() = 0;
  // Called by subclasses with raw bytes read; splits them into lines.
  void on_bytes(const char* data, size_t n);
  void on_write_done(bool ok);

 private:
  void write_next();

  uint64_t id_;
  std::string name_;
  LineHandler on_line_;
  CloseHandler on_close_;
  std::deque<std::string> out_;
  size_t pending_bytes_ = 0;
  bool writing_ = false;
  bool closed_ = false;
  bool paused_ = false;
  bool read_pending_ = false;  // a read should be issued on resume
  uint64_t dropped_lines_ = 0;
  gcode::LineSplitter splitter_{kMaxLineBytes, /*cr_is_newline=*/true};

 protected:
  void note_read_wanted() { read_pending_ = true; }
  bool take_read_wanted() {
    const bool r = read_pending_;
    read_pending_ = false;
    return r;
  }
};

// A session over any Asio stream (local socket, posix stream descriptor).
template <class Stream>
class StreamSession final : public ClientSession {
 public:
  StreamSession(uint64_t id, std::string name, Stream stream)
      : ClientSession(id, std::move(name)), stream_(std::move(stream)) {}

  void start() override { do_read(); }

 protected:
  void do_read() override {
    if (closed()) return;
    if (paused()) {
      note_read_wanted();
      return;
    }
    auto self = shared_from_this();
    stream_.async_read_some(boost::asio::buffer(buf_),
                            [this, self](const boost::system::error_code& ec, size_t n) {
                              if (ec) {
                                close();
                                return;
                              }
                              on_bytes(buf_.data(), n);
                              do_read();
                            });
  }
  void do_write(const std::string& data) override {
    auto self = shared_from_this();
    boost::asio::async_write(stream_, boost::asio::buffer(data),
                             [this, self](const boost::system::error_code& ec, size_t) {
                               on_write_done(!ec);
                             });
  }
  void do_close() override {
    boost::system::error_code ignored;
    stream_.close(ignored);
  }

 private:
  Stream stream_;
  std::array<char, 8192> buf_{};
};

}  // namespace feedloop::daemon
