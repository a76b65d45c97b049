#include "daemon/client_session.hpp"

namespace feedloop::daemon {

bool ClientSession::send_line(std::string_view line, bool droppable) {
  if (closed_) return false;
  if (droppable && pending_bytes_ > kMaxPendingBytes / 2) {
    ++dropped_lines_;
    return true;
  }
  if (pending_bytes_ + line.size() + 1 > kMaxPendingBytes) {
    close();  // a client that does not read is cut off; motion does not wait for it
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
  do_write(out_.front());
}

void ClientSession::on_write_done(bool ok) {
  if (!ok) {
    close();
    return;
  }
  if (!out_.empty()) {
    pending_bytes_ -= out_.front().size();
    out_.pop_front();
  }
  write_next();
}

void ClientSession::resume_reading() {
  if (!paused_) return;
  paused_ = false;
  if (take_read_wanted()) do_read();
}

void ClientSession::close() {
  if (closed_) return;
  closed_ = true;
  do_close();
  if (on_close_) on_close_(*this);
}

void ClientSession::on_bytes(const char* data, size_t n) {
  splitter_.feed(std::string_view(data, n), [this](const gcode::SplitLine& line) {
    if (closed_ || !on_line_) return;
    if (line.too_long) {
      on_line_(*this, {}, true);
    } else if (!line.text.empty()) {
      on_line_(*this, line.text, false);
    }
  });
}

}  // namespace feedloop::daemon
