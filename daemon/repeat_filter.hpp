// Log lines that repeat: the first one of a kind is logged, the repeats are counted, and one line
// says how many there were ("... repeated 198 times in 4.2 s") when a different message comes,
// when `window_ns` has passed since the first, or at flush(). A fault that refuses every later
// command logs two lines instead of one per command.
// Owner: the I/O thread (not thread-safe).
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>

namespace feedloop::daemon {

class RepeatFilter {
 public:
  explicit RepeatFilter(int64_t window_ns = 10'000'000'000) : window_ns_(window_ns) {}

  // What to log for an occurrence of `key` at `now_ns`: `summary` (if not empty) reports the
  // repeats of the previous key, to be logged first; returns true when this occurrence itself
  // is to be logged.
  bool admit(std::string_view key, int64_t now_ns, std::string* summary) {
    summary->clear();
    if (key == key_ && now_ns - first_ns_ < window_ns_) {
      ++repeats_;
      last_ns_ = now_ns;
      return false;
    }
    take_summary(summary);
    key_.assign(key);
    first_ns_ = last_ns_ = now_ns;
    repeats_ = 0;
    return true;
  }
  // The pending summary once `window_ns` has passed since the key's first occurrence (or at
  // once with force); empty when there is nothing to report.
  std::string flush(int64_t now_ns, bool force = false) {
    std::string s;
    if (repeats_ > 0 && (force || now_ns - first_ns_ >= window_ns_)) {
      take_summary(&s);
      key_.clear();
    }
    return s;
  }
  uint64_t suppressed_total() const { return suppressed_total_; }

 private:
  void take_summary(std::string* out) {
    if (repeats_ == 0) return;
    char secs[32];
    std::snprintf(secs, sizeof secs, "%.1f", static_cast<double>(last_ns_ - first_ns_) * 1e-9);
    *out = "last message repeated " + std::to_string(repeats_) + " times in " + secs + " s: " + key_;
    suppressed_total_ += repeats_;
    repeats_ = 0;
  }

  int64_t window_ns_;
  std::string key_;
  int64_t first_ns_ = 0, last_ns_ = 0;
  uint64_t repeats_ = 0;
  uint64_t suppressed_total_ = 0;
};

}  // namespace feedloop::daemon
