// One connected client on any line-based channel (Unix socket, pty, JSON API socket).
// Lives on the I/O thread. Client I/O never delays the machine: everything a client can make the
// daemon do is bounded.
//
// - Input: lines go into a bounded queue (kMaxInputBytes; reading stops while it is full, so a
//   client that writes faster than it is served waits in its own socket buffer). The queue is
//   worked off at most `lines_per_turn` lines at a time, then the other clients and the machine's
//   completions get their turn (round robin on the I/O loop). Urgent lines (M112,
//   emergency_stop) bypass the queue, the pause and the rate limit.
// - Rate: a token bucket (`lines_per_s`, `burst`). A line costs a token unless the daemon gives
//   it back (refund(): the line went to the machine, whose queue paces it). With no token left
//   the client is throttled: its lines wait, one log line says so. A client that stays throttled
//   with lines waiting for `drop_after_s` is flooding: it is disconnected with a log line.
// - Output: a bounded queue (kMaxPendingBytes). A client that does not read its replies is
//   disconnected (log line); droppable lines (status notifications) are skipped first.
#pragma once

#include <boost/asio.hpp>

#include <array>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <string>
#include <string_view>

#include "gcode/line_splitter.hpp"

namespace feedloop::daemon {

// What a client may make the I/O thread do (per session).
struct InputLimits {
  double lines_per_s = 0.0;    // charged lines per second (0: no limit)
  double burst = 0.0;          // charged lines at once, above the rate
  double drop_after_s = 5.0;   // throttled this long, lines always waiting: disconnected
  size_t lines_per_turn = 16;  // lines handled before the other clients get their turn
};

class ClientSession : public std::enable_shared_from_this<ClientSession> {
 public:
  // Receives each non-empty input line (without its line ending); a line over kMaxLineBytes
  // arrives once as too_long with empty text.
  using LineHandler = std::function<void(ClientSession&, std::string_view line, bool too_long)>;
  using CloseHandler = std::function<void(ClientSession&)>;
  using UrgentTest = std::function<bool(std::string_view line)>;
  using ArrivalHook = std::function<void(std::string_view line)>;
  using WriteGuard = std::function<void()>;

  ClientSession(uint64_t id, std::string name) : id_(id), name_(std::move(name)) {}
  virtual ~ClientSession() = default;

  uint64_t id() const { return id_; }
  const std::string& name() const { return name_; }
  bool closed() const { return closed_; }

  void set_handlers(LineHandler on_line, CloseHandler on_close) {
    on_line_ = std::move(on_line);
    on_close_ = std::move(on_close);
  }
  void set_limits(const InputLimits& limits);
  // Lines for which `urgent` is true are handled as they arrive, ahead of everything.
  void set_urgent(UrgentTest urgent) { urgent_ = std::move(urgent); }
  // Sees every line as it arrives, before it waits in the queue (which it still joins): Marlin's
  // emergency parser acts on M108 at once and answers it in order all the same.
  void set_on_arrival(ArrivalHook hook) { on_arrival_ = std::move(hook); }
  // Runs before each write to the client (the pty keeps its slave side from echoing there).
  void set_before_write(WriteGuard guard) { before_write_ = std::move(guard); }

  // Queues `line` plus '\n'. Returns false (and closes the session) when the client has more
  // than max_pending_bytes unread. `droppable` lines (status notifications) are skipped instead
  // when the queue is over half full.
  bool send_line(std::string_view line, bool droppable = false);
  uint64_t dropped_lines() const { return dropped_lines_; }

  // Lines wait while paused (backpressure: the machine's queue is full); reading goes on until
  // the input queue is full, so urgent lines are still seen.
  void pause_reading() { paused_ = true; }
  void resume_reading();
  bool paused() const { return paused_; }

  // The line being handled went to the machine: it costs no token.
  void refund();
  // Periodic (the daemon's tick): refills the bucket and works off waiting lines.
  void service() { drain(); }
  bool throttled() const { return throttled_; }
  uint64_t throttle_episodes() const { return throttle_episodes_; }
  size_t queued_lines() const { return in_.size(); }

  virtual void start() = 0;
  void close();

  static constexpr size_t kMaxPendingBytes = 1 << 20;
  static constexpr size_t kMaxLineBytes = 256 * 1024;
  static constexpr size_t kMaxInputBytes = 64 * 1024;  // queued input lines (plus one read)

 protected:
  virtual void do_write(const std::string& data) = 0;  // one async write of `data`
  virtual void do_close() = 0;
  virtual void do_read() = 0;
  // Runs `fn` later on the I/O loop; false when the session cannot (then lines are handled at
  // once, without turns).
  virtual bool defer(std::function<void()> /*fn*/) { return false; }
  // Called by subclasses with raw bytes read; splits them into lines.
  void on_bytes(const char* data, size_t n);
  void on_write_done(bool ok);
  // False while the input queue is full: the subclass does not read (note_read_wanted).
  bool input_room() const { return in_bytes_ < kMaxInputBytes; }

 private:
  struct InLine {
    std::string text;
    bool too_long = false;
  };
  void write_next();
  void drain();
  void refill(int64_t now_ns);
  void on_throttled(int64_t now_ns);

  uint64_t id_;
  std::string name_;
  LineHandler on_line_;
  CloseHandler on_close_;
  UrgentTest urgent_;
  ArrivalHook on_arrival_;
  WriteGuard before_write_;
  std::deque<std::string> out_;
  std::string writing_buf_;  // the lines of the write in progress, coalesced
  size_t pending_bytes_ = 0;
  bool writing_ = false;
  bool closed_ = false;
  bool paused_ = false;
  bool read_pending_ = false;  // a read should be issued when there is room again
  uint64_t dropped_lines_ = 0;
  gcode::LineSplitter splitter_{kMaxLineBytes, /*cr_is_newline=*/true};

  std::deque<InLine> in_;
  size_t in_bytes_ = 0;
  bool draining_ = false;
  bool drain_deferred_ = false;
  InputLimits limits_;
  double tokens_ = 0.0;
  int64_t refill_ns_ = 0;
  bool throttled_ = false;
  int64_t throttled_since_ns_ = 0;
  int64_t throttle_logged_ns_ = 0;
  uint64_t throttle_episodes_ = 0;

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
    if (!input_room()) {
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
    boost::asio::async_write(
        stream_, boost::asio::buffer(data),
        [this, self](const boost::system::error_code& ec, size_t) { on_write_done(!ec); });
  }
  void do_close() override {
    boost::system::error_code ignored;
    stream_.close(ignored);
  }
  bool defer(std::function<void()> fn) override {
    boost::asio::post(stream_.get_executor(),
                      [self = shared_from_this(), fn = std::move(fn)] { fn(); });
    return true;
  }

 private:
  Stream stream_;
  std::array<char, 8192> buf_{};
};

}  // namespace feedloop::daemon
