#include "core/free_cores.hpp"

#include <sched.h>

#include <algorithm>
#include <chrono>
#include <charconv>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>

namespace feedloop::core {

std::optional<uint32_t> procs_running_from_stat(std::string_view text) {
  constexpr std::string_view kKey = "procs_running ";
  size_t at = 0;
  while (at < text.size()) {
    const size_t end = std::min(text.find('\n', at), text.size());
    const std::string_view line = text.substr(at, end - at);
    if (line.substr(0, kKey.size()) == kKey) {
      const std::string_view digits = line.substr(kKey.size());
      uint32_t n = 0;
      const auto [ptr, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), n);
      if (ec != std::errc{} || ptr == digits.data()) return std::nullopt;
      return n;
    }
    at = end + 1;
  }
  return std::nullopt;
}

namespace {
std::optional<uint32_t> read_procs_running() {
  std::ifstream in("/proc/stat");
  if (!in) return std::nullopt;
  std::ostringstream text;
  text << in.rdbuf();
  return procs_running_from_stat(text.str());
}
}  // namespace

uint32_t free_cores() {
  cpu_set_t set;
  CPU_ZERO(&set);
  uint32_t allowed = 1;
  if (sched_getaffinity(0, sizeof(set), &set) == 0)
    allowed = std::max(1, CPU_COUNT(&set));
  std::optional<uint32_t> least;
  for (int sample = 0; sample < 3; ++sample) {
    if (sample > 0) std::this_thread::sleep_for(std::chrono::microseconds(500));
    const auto n = read_procs_running();
    if (!n) return allowed;
    least = least ? std::min(*least, *n) : *n;
  }
  // The count includes the calling thread (running while it reads).
  const uint32_t others = *least > 0 ? *least - 1 : 0;
  return others >= allowed ? 1 : std::max<uint32_t>(1, allowed - others);
}

}  // namespace feedloop::core
