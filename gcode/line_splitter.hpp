// Cuts a byte stream (a file read in chunks, a socket, a pty) into lines with a hard cap on the
// length of one line, so memory stays bounded on any input: a line longer than the cap is
// reported once as `too_long` (with its full length) and its bytes are dropped up to the next
// newline. Lines that lie inside one fed chunk are handed out as views into that chunk (no copy);
// only a line split across chunks is assembled in an internal buffer of at most the cap.
//
// Line ends: '\n'; a '\r' just before it is dropped ("\r\n" files). With cr_is_newline (serial
// channels, where some hosts end lines with '\r' alone) '\r' also ends a line and "\r\n" counts
// as one end.
// Owner: whichever thread reads the stream; not thread-safe.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

namespace feedloop::gcode {

struct SplitLine {
  std::string_view text;     // the line without its end; empty when too_long
  int64_t number = 0;        // 1-based physical line number in the stream
  size_t length_bytes = 0;   // full length without the line end (> cap when too_long)
  bool too_long = false;
};

class LineSplitter {
 public:
  static constexpr size_t kDefaultMaxLineBytes = 256 * 1024;

  explicit LineSplitter(size_t max_line_bytes = kDefaultMaxLineBytes, bool cr_is_newline = false)
      : max_line_bytes_(max_line_bytes == 0 ? 1 : max_line_bytes), cr_is_newline_(cr_is_newline) {}

  size_t max_line_bytes() const { return max_line_bytes_; }
  int64_t lines() const { return line_number_; }
  // Bytes held for an unfinished line (never more than max_line_bytes()).
  size_t buffered_bytes() const { return pending_.size(); }

  // Feeds bytes; calls on_line(const SplitLine&) for every line completed by them. The view in
  // SplitLine is valid only during the call.
  template <class F>
  void feed(std::string_view bytes, F&& on_line) {
    const char* p = bytes.data();
    const char* const end = p + bytes.size();
    if (skip_lf_ && p < end) {  // the '\n' of a "\r\n" split across chunks
      skip_lf_ = false;
      if (*p == '\n') ++p;
    }
    while (p < end) {
      const char* eol = find_eol(p, end);
      if (eol == nullptr) {
        append(p, end);
        return;
      }
      if (pending_.empty() && pending_length_ == 0) {
        emit(std::string_view(p, static_cast<size_t>(eol - p)), on_line);
      } else {
        append(p, eol);
        emit_pending(on_line);
      }
      p = eol + 1;
      if (cr_is_newline_ && *eol == '\r') {
        if (p < end) {
          if (*p == '\n') ++p;
        } else {
          skip_lf_ = true;
        }
      }
    }
  }

  // End of stream: a last line without a line end is handed out.
  template <class F>
  void finish(F&& on_line) {
    if (!pending_.empty() || pending_length_ != 0) emit_pending(on_line);
    skip_lf_ = false;
  }

 private:
  const char* find_eol(const char* p, const char* end) const {
    if (!cr_is_newline_)
      return static_cast<const char*>(std::memchr(p, '\n', static_cast<size_t>(end - p)));
    for (; p < end; ++p)
      if (*p == '\n' || *p == '\r') return p;
    return nullptr;
  }

  // Adds [p, q) to the unfinished line, dropping bytes beyond the cap.
  void append(const char* p, const char* q) {
    const size_t n = static_cast<size_t>(q - p);
    pending_length_ += n;
    if (pending_length_ > max_line_bytes_) {
      pending_.clear();  // keeps capacity (at most the cap); the line is reported as too long
      return;
    }
    pending_.append(p, n);
  }

  template <class F>
  void emit(std::string_view text, F& on_line) {
    SplitLine line;
    line.number = ++line_number_;
    if (text.size() > max_line_bytes_) {  // the cap counts raw bytes, a '\r' included
      line.too_long = true;
      line.length_bytes = text.size();
    } else {
      if (!cr_is_newline_ && !text.empty() && text.back() == '\r') text.remove_suffix(1);
      line.text = text;
      line.length_bytes = text.size();
    }
    on_line(static_cast<const SplitLine&>(line));
  }

  template <class F>
  void emit_pending(F& on_line) {
    if (pending_length_ > max_line_bytes_) {
      SplitLine line;
      line.number = ++line_number_;
      line.length_bytes = pending_length_;
      line.too_long = true;
      on_line(static_cast<const SplitLine&>(line));
    } else {
      emit(std::string_view(pending_), on_line);
    }
    pending_.clear();
    pending_length_ = 0;
  }

  size_t max_line_bytes_;
  bool cr_is_newline_;
  bool skip_lf_ = false;
  int64_t line_number_ = 0;
  size_t pending_length_ = 0;  // bytes of the unfinished line seen so far (may exceed the cap)
  std::string pending_;
};

}  // namespace feedloop::gcode
