// A one-line progress display: a bar on a terminal (redrawn at most 10 times a second), plain
// percentage lines every 10 % otherwise (logs, CI).
#pragma once

#include <unistd.h>  // isatty

#include <chrono>
#include <cstdio>
#include <string>

namespace feedloop::cli {

class Progress {
 public:
  explicit Progress(std::string label) : label_(std::move(label)), tty_(::isatty(2) != 0) {}

  void update(double fraction, const std::string& detail = {}) {
    const auto now = std::chrono::steady_clock::now();
    if (tty_) {
      if (now - last_ < std::chrono::milliseconds(100) && fraction < 1.0) return;
      last_ = now;
      const int width = 30;
      const int filled = static_cast<int>(fraction * width + 0.5);
      std::fprintf(stderr, "\r%s [%s%s] %5.1f%% %s\033[K", label_.c_str(),
                   std::string(static_cast<size_t>(filled), '#').c_str(),
                   std::string(static_cast<size_t>(width - filled), '.').c_str(), fraction * 100.0,
                   detail.c_str());
    } else {
      const int decile = static_cast<int>(fraction * 10.0);
      if (decile <= last_decile_) return;
      last_decile_ = decile;
      std::fprintf(stderr, "%s %3d%% %s\n", label_.c_str(), decile * 10, detail.c_str());
    }
    std::fflush(stderr);
  }
  void finish() {
    if (tty_) std::fprintf(stderr, "\n");
  }

 private:
  std::string label_;
  bool tty_;
  int last_decile_ = -1;
  std::chrono::steady_clock::time_point last_{};
};

}  // namespace feedloop::cli
