#include "daemon/client_session.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>  // std::min
#include <chrono>

namespace feedloop::daemon {

namespace {
int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}
constexpr int64_t kThrottleLogEveryNs = 10'000'000'000;  // one "throttled" line per client per 10 s
constexpr size_t kMaxWriteBytes = 64 * 1024;             // queued lines coalesced into one write
constexpr size_t kLineOverheadBytes = 64;  // what a queued line counts beyond its text
}  // namespace

void ClientSession::set_limits(const InputLimits& limits) {
  limits_ = limits;
  if (limits_.lines_per_turn == 0) limits_.lines_per_turn = 1;
  tokens_ = limits_.burst;
  refill_ns_ = steady_ns();
}

bool ClientSession::send_line(std::string_view line, bool droppable) {
  if (closed_) return false;
  if (droppable && pending_bytes_ > kMaxPendingBytes / 2) {
    if (dropped_lines_++ == 0)
      spdlog::warn("{} reads slower than its notifications arrive: skipping them", name_);
    return true;
  }
  if (pending_bytes_ + line.size() + 1 > kMaxPendingBytes) {
    // A client that does not read is cut off; motion does not wait for it.
    spdlog::warn("{} dropped: it has not read {} bytes of replies", name_, pending_bytes_);
    close();
    return false;
  }
  std::string s;
  s.reserve(line.size() + 1);
  s.append(line);
  s.push_back('\n');
  pending_bytes_ += s.size();
  out_.push_back(std::move(s));
  if (!writing_) write_next();
  return true;
}

void ClientSession::write_next() {
  if (out_.empty() || closed_) {
    writing_ = false;
    return;
  }
  writing_ = true;
  // The lines queued meanwhile go out in one write (one system call, one wake-up of the reader).
  writing_buf_ = std::move(out_.front());
  out_.pop_front();
  while (!out_.empty() && writing_buf_.size() + out_.front().size() <= kMaxWriteBytes) {
    writing_buf_ += out_.front();
    out_.pop_front();
  }
  if (before_write_) before_write_();
  do_write(writing_buf_);
}

void ClientSession::on_write_done(bool ok) {
  if (!ok) {
    close();
    return;
  }
  pending_bytes_ -= std::min(pending_bytes_, writing_buf_.size());
  writing_buf_.clear();
  write_next();
}

void ClientSession::resume_reading() {
  if (!paused_) return;
  paused_ = false;
  drain();
}

void ClientSession::close() {
  if (closed_) return;
  closed_ = true;
  in_.clear();
  in_bytes_ = 0;
  do_close();
  if (on_close_) on_close_(*this);
}

void ClientSession::refund() {
  if (limits_.lines_per_s > 0.0) tokens_ = std::min(limits_.burst, tokens_ + 1.0);
}

void ClientSession::refill(int64_t now_ns) {
  if (limits_.lines_per_s <= 0.0) return;
  const double dt_s = static_cast<double>(now_ns - refill_ns_) * 1e-9;
  refill_ns_ = now_ns;
  if (dt_s > 0.0) tokens_ = std::min(limits_.burst, tokens_ + dt_s * limits_.lines_per_s);
}

void ClientSession::on_throttled(int64_t now_ns) {
  if (!throttled_) {
    throttled_ = true;
    throttled_since_ns_ = now_ns;
    ++throttle_episodes_;
    if (throttle_logged_ns_ == 0 || now_ns - throttle_logged_ns_ > kThrottleLogEveryNs) {
      throttle_logged_ns_ = now_ns;
      spdlog::warn("{} throttled: more than {:.0f} requests/s (burst {:.0f}); its lines wait",
                   name_, limits_.lines_per_s, limits_.burst);
    }
    return;
  }
  const double for_s = static_cast<double>(now_ns - throttled_since_ns_) * 1e-9;
  if (for_s > limits_.drop_after_s) {
    spdlog::warn("{} dropped: flooding, more than {:.0f} requests/s without a pause for {:.1f} s",
                 name_, limits_.lines_per_s, for_s);
    close();
  }
}

void ClientSession::drain() {
  if (draining_ || closed_) return;
  draining_ = true;
  const int64_t now = steady_ns();
  refill(now);
  const bool limited = limits_.lines_per_s > 0.0;
  size_t handled = 0;
  while (!in_.empty() && !closed_ && !paused_) {
    if (handled >= limits_.lines_per_turn && defer([this] {
          drain_deferred_ = false;
          drain();
        })) {
      drain_deferred_ = true;
      break;
    }
    if (limited && tokens_ < 1.0) {
      on_throttled(now);
      break;
    }
    InLine line = std::move(in_.front());
    in_.pop_front();
    in_bytes_ -= line.text.size() + kLineOverheadBytes;
    if (limited) tokens_ -= 1.0;
    ++handled;
    if (on_line_) on_line_(*this, line.text, line.too_long);
  }
  if (in_.empty()) throttled_ = false;  // the client paused: the episode is over
  draining_ = false;
  if (!closed_ && input_room() && take_read_wanted()) do_read();
}

void ClientSession::on_bytes(const char* data, size_t n) {
  splitter_.feed(std::string_view(data, n), [this](const gcode::SplitLine& line) {
    if (closed_) return;
    if (line.too_long) {
      in_bytes_ += kLineOverheadBytes;
      in_.push_back(InLine{{}, true});
    } else if (!line.text.empty()) {
      if (on_arrival_) on_arrival_(line.text);
      if (urgent_ && urgent_(line.text)) {  // ahead of the queue, the pause and the rate limit
        if (on_line_) on_line_(*this, line.text, false);
        return;
      }
      in_bytes_ += line.text.size() + kLineOverheadBytes;
      in_.push_back(InLine{std::string(line.text), false});
    }
  });
  if (!drain_deferred_) drain();
}

}  // namespace feedloop::daemon
