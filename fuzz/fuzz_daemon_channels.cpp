// libFuzzer target for the daemon's client channels with a simulated machine: every input starts
// a fresh feedloopd (Daemon, embedded simulated printer, virtual time, flight recorder on), opens
// a client connection to its G-code socket (Marlin host protocol) or, when the first byte is odd,
// its JSON API socket, writes the rest of the input in chunks (first byte >> 1 picks the size),
// and runs the daemon's I/O loop until nothing more comes back and the machine is idle (at most
// 1 s: a slow move is cut short, not a finding). Lines take the whole path of a real client:
// listener, ClientSession, HostProtocol or handle_json_request, queries, ownership, the machine
// queue, the recorder, and the replies.
// Besides crashes, sanitizer reports and escaping exceptions (which end the daemon), these trap:
// the daemon closes the connection of a client that reads everything; a G-code channel reply
// line that is not one a Marlin host expects (ok, Error:, echo:, Resend:, X:..., FIRMWARE_NAME:,
// a host prompt, M119's and M220's reports, temperatures);
// more `ok` lines than lines sent; a JSON channel reply that is not one JSON object per line; the
// status object (what `status` and subscriptions send) not serialising.
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <string_view>

#include "config/config.hpp"
#include "daemon/daemon.hpp"
#include "fuzz/fuzz_input.hpp"

namespace {

using namespace feedloop;
using fuzz::check;
using WallClock = std::chrono::steady_clock;

// A config like the tests' (DaemonFixture): sockets and recordings in a scratch directory
// (on tmpfs when there is one: every print's recording is synced at its end).
const config::MachineConfig& fuzz_config() {
  static const config::MachineConfig cfg = [] {
    std::error_code ec;
    std::filesystem::path base = "/dev/shm";
    if (!std::filesystem::is_directory(base, ec)) base = std::filesystem::temp_directory_path();
    std::string dir = (base / "feedloop-fuzz-XXXXXX").string();
    check(::mkdtemp(dir.data()) != nullptr);
    ::setenv("RUNTIME_DIRECTORY", dir.c_str(), 1);  // the channels belong in the runtime directory
    config::MachineConfig c = config::default_config();
    c.sockets.unix_socket = dir + "/feedloop.sock";
    c.sockets.api_socket = dir + "/api.sock";
    c.sockets.pty_link = dir + "/ttyFeedloop";
    c.servo.realtime_priority = 0;
    c.servo.lock_memory = false;
    c.recorder.directory = dir + "/recordings";
    c.recorder.keep_files = 4;
    return c;
  }();
  return cfg;
}

bool starts_with(std::string_view s, std::string_view p) {
  return s.substr(0, p.size()) == p;
}

// The lines a Marlin host may get (gcode/host_protocol.hpp, Daemon::answer_query; M0 / M600's
// host prompt, daemon_user_wait.cpp; M119's report; M220's factor; M155's auto-report).
void check_marlin_reply(std::string_view line) {
  const bool endstop =
      line.size() > 6 && std::string_view("xyz").find(line[0]) != std::string_view::npos &&
      (starts_with(line.substr(1), "_min: ") || starts_with(line.substr(1), "_max: "));
  check(starts_with(line, "ok") || starts_with(line, "Error:") || starts_with(line, "echo:") ||
        starts_with(line, "Resend: ") || starts_with(line, "X:") ||
        starts_with(line, "FIRMWARE_NAME:") || starts_with(line, "//action:prompt_") ||
        starts_with(line, "Reporting endstop status") || endstop || starts_with(line, "FR:") ||
        starts_with(line, " T:") || starts_with(line, "T:"));
}

void check_json_reply(std::string_view line) {
  const auto j = nlohmann::json::parse(line, nullptr, /*allow_exceptions=*/false);
  check(!j.is_discarded() && j.is_object() && j.value("jsonrpc", "") == "2.0");
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);
  (void)fuzz_config();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const bool api = data[0] & 1;
  const size_t chunk = 1 + (data[0] >> 1) * 17;
  const std::string_view input(reinterpret_cast<const char*>(data + 1), size - 1);

  daemon::DaemonOptions options;
  options.ownership_idle_s = 0.05;
  options.virtual_time = true;
  daemon::Daemon d(fuzz_config(), options);
  check(d.start().ok());

  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  check(fd >= 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  const std::string& path = api ? d.api_socket_path() : d.socket_path();
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  check(::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) == 0);

  std::string out;
  bool peer_closed = false;
  auto pump = [&](int ms) {
    d.io().run_for(std::chrono::milliseconds(ms));
    char buf[65536];
    for (;;) {
      const ssize_t n = ::read(fd, buf, sizeof buf);
      if (n > 0) out.append(buf, static_cast<size_t>(n));
      if (n == 0) peer_closed = true;
      if (n <= 0) break;
    }
  };
  const auto deadline = WallClock::now() + std::chrono::seconds(1);
  size_t sent = 0;
  while (sent < input.size() && WallClock::now() < deadline) {
    const ssize_t w = ::write(fd, input.data() + sent, std::min(chunk, input.size() - sent));
    check(w > 0 || errno == EAGAIN);
    if (w > 0) sent += static_cast<size_t>(w);
    pump(1);
  }
  // Until quiet: no reply for 20 ms and the machine idle with an empty queue.
  auto last_reply = WallClock::now();
  while (WallClock::now() < deadline && !peer_closed) {
    const size_t before = out.size();
    pump(5);
    if (out.size() != before) last_reply = WallClock::now();
    const nlohmann::json st = d.status();
    if (WallClock::now() - last_reply > std::chrono::milliseconds(20) && st["state"] != "busy" &&
        st["queue"]["depth"] == 0)
      break;
  }
  check(!peer_closed);
  ::close(fd);

  // What `status` and every subscription send: valid UTF-8 without to_wire()'s replacement
  // (outside text is made valid where it enters), so the strict dump() does not throw.
  (void)d.status().dump();
  size_t oks = 0, lines_sent = 1;
  for (char c : input.substr(0, sent)) lines_sent += c == '\n' || c == '\r';
  for (size_t b = 0; b < out.size();) {
    size_t e = out.find('\n', b);
    if (e == std::string::npos) e = out.size();
    const std::string_view line(out.data() + b, e - b);
    if (api)
      check_json_reply(line);
    else
      check_marlin_reply(line);
    oks += starts_with(line, "ok");
    b = e + 1;
  }
  if (!api) check(oks <= lines_sent);
  return 0;
}
