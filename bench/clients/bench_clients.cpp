// bench_clients: does client I/O delay the machine? A real-time print on feedloopd's embedded
// simulated printer, once with no clients and once with N clients polling JSON `status` every
// P ms (defaults: 50 clients, 10 ms), several repetitions each, interleaved (A B B A ...: the
// machine is shared and noisy, so drift falls on both conditions alike). Per run it prints the
// servo loop's deadline misses, wake-up latency p99/max, lost-step events, late cycles and
// rejected lines, machine faults, the pollers' reply round trips, and the daemon's CPU time (all
// threads, and its I/O thread alone); then each condition's median and range side by side.
//
// Each run starts a fresh feedloopd (the binary, as users run it: SCHED_FIFO and mlockall when
// permitted) with its runtime and state directories in a temporary directory, streams the G-code
// file through feedloop.sock as a Marlin host (window of 4 lines, like `feedloop print`) with
// heater waits (M109/M190) sent as plain set-points (the bench measures motion, not heating),
// stops sending after --seconds of streaming (0: the whole file), waits for the machine to go
// idle (or to stop on a fault), and reads the counters through the JSON API before and after.
// --priority 0 runs the servo thread without SCHED_FIFO, as for a user without CAP_SYS_NICE.
//
// --load web: the daemon runs with its web server on (docs/web.md) and the N clients are hostile
// web clients instead of pollers (WebLoad below): slow readers that ask for the printer objects
// and never read the replies, WebSocket frames that announce 64 MiB, more connections than the
// server's limit that send half a request header and wait (slow loris), malformed requests and
// frames, and a flood of ordinary HTTP queries. The question is the same: deadline misses, e_t
// and lost steps with and without them, side by side.
//
//   build/bench/clients/bench_clients [--clients 50] [--poll-ms 10] [--reps 3] [--seconds 10]
//        [--load json|web] [--priority PRIO] [--file examples/gcode/cube20_3layers.gcode]
//        [--feedloopd PATH] [--json FILE]
#include <arpa/inet.h>   // htons
#include <fcntl.h>       // open
#include <netinet/in.h>  // sockaddr_in
#include <poll.h>        // poll
#include <signal.h>      // kill
#include <sys/socket.h>  // socket
#include <sys/time.h>    // timeval
#include <sys/un.h>      // sockaddr_un
#include <sys/wait.h>    // waitpid
#include <unistd.h>      // fork, execv

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench/bench_json.hpp"
#include "config/config.hpp"

namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

struct Args {
  int clients = 50;
  double poll_ms = 10.0;
  int reps = 3;
  double seconds = 10.0;  // the daemon takes ~43 s of the cube's motion in the first 0.1 s
  std::string file = "examples/gcode/cube20_3layers.gcode";
  std::string feedloopd = FEEDLOOPD_PATH;
  std::string json_path;
  int priority = -1;  // the servo thread's SCHED_FIFO priority; -1: the config's (80), 0: none
  bool web = false;   // --load web: hostile web clients instead of status pollers
};

double since_s(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// A blocking line connection to a Unix socket with timeouts.
class Conn {
 public:
  ~Conn() { close(); }
  bool connect(const std::string& path, double timeout_s) {
    const auto t0 = Clock::now();
    while (since_s(t0) < timeout_s) {
      fd_ = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
      sockaddr_un addr{};
      addr.sun_family = AF_UNIX;
      std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", path.c_str());
      if (::connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0) return true;
      ::close(fd_);
      fd_ = -1;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return false;
  }
  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  bool send(std::string_view text) {
    size_t off = 0;
    while (off < text.size()) {
      const ssize_t n = ::send(fd_, text.data() + off, text.size() - off, MSG_NOSIGNAL);
      if (n <= 0) return false;
      off += static_cast<size_t>(n);
    }
    return true;
  }
  // One line without its '\n'; nullopt on timeout or a closed connection.
  std::optional<std::string> read_line(double timeout_s) {
    const auto t0 = Clock::now();
    for (;;) {
      if (const size_t nl = buf_.find('\n'); nl != std::string::npos) {
        std::string line = buf_.substr(0, nl);
        buf_.erase(0, nl + 1);
        return line;
      }
      const double left_ms = (timeout_s - since_s(t0)) * 1000.0;
      if (left_ms <= 0) return std::nullopt;
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, static_cast<int>(left_ms) + 1) <= 0) continue;
      char chunk[8192];
      const ssize_t n = ::recv(fd_, chunk, sizeof chunk, 0);
      if (n <= 0) return std::nullopt;
      buf_.append(chunk, static_cast<size_t>(n));
    }
  }

 private:
  int fd_ = -1;
  std::string buf_;
};

std::optional<json> request_status(Conn& c, int id) {
  if (!c.send("{\"jsonrpc\":\"2.0\",\"id\":" + std::to_string(id) + ",\"method\":\"status\"}\n"))
    return std::nullopt;
  for (;;) {
    auto line = c.read_line(5.0);
    if (!line) return std::nullopt;
    json j = json::parse(*line, nullptr, false);
    if (j.is_discarded() || !j.contains("id")) continue;  // a notification
    if (!j.contains("result")) return std::nullopt;
    return j["result"];
  }
}

// One status poller: a request every poll_ms (absolute schedule; a late one is not made up), the
// reply waited for. Round trips in microseconds.
struct Poller {
  std::vector<float> rtt_us;
  uint64_t replies = 0, failures = 0;
  bool connected = false;
};

void poll_loop(const std::string& api, double poll_ms, const std::atomic<bool>& stop, Poller& p) {
  Conn c;
  if (!c.connect(api, 5.0)) return;
  p.connected = true;
  p.rtt_us.reserve(1 << 14);
  const auto period = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double, std::milli>(poll_ms));
  auto next = Clock::now();
  int id = 0;
  while (!stop.load(std::memory_order_relaxed)) {
    const auto t0 = Clock::now();
    if (!c.send("{\"jsonrpc\":\"2.0\",\"id\":" + std::to_string(++id) +
                ",\"method\":\"status\"}\n")) {
      ++p.failures;
      return;
    }
    auto line = c.read_line(5.0);
    if (!line || line->find("\"result\"") == std::string::npos) {
      ++p.failures;
      if (!line) return;  // timed out or disconnected
    } else {
      ++p.replies;
      p.rtt_us.push_back(
          static_cast<float>(std::chrono::duration<double, std::micro>(Clock::now() - t0).count()));
    }
    next += period;
    const auto now = Clock::now();
    if (next < now) next = now;  // behind: no burst to catch up
    std::this_thread::sleep_until(next);
  }
}

// --- Hostile web clients (--load web) ---------------------------------------------------------

// A TCP connection to 127.0.0.1 with short timeouts; every call gives up when `stop` is set.
class Tcp {
 public:
  ~Tcp() { close(); }
  bool connect(int port) {
    close();
    fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd_ < 0) return false;
    timeval tv{0, 200'000};
    ::setsockopt(fd_, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
      close();
      return false;
    }
    return true;
  }
  // A small receive buffer: the slow readers' replies back up in the daemon sooner.
  void small_receive_buffer() {
    int n = 4096;
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &n, sizeof n);
  }
  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  bool open() const { return fd_ >= 0; }
  // Sends everything unless the peer closes, `stop` is set or a send times out 25 times in a row.
  bool send(std::string_view d, const std::atomic<bool>& stop, uint64_t* bytes) {
    size_t off = 0;
    int stalls = 0;
    while (off < d.size() && !stop.load(std::memory_order_relaxed)) {
      const ssize_t n = ::send(fd_, d.data() + off, d.size() - off, MSG_NOSIGNAL);
      if (n > 0) {
        off += static_cast<size_t>(n);
        *bytes += static_cast<uint64_t>(n);
        stalls = 0;
        continue;
      }
      if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK) && ++stalls < 25) continue;
      return false;
    }
    return off == d.size();
  }
  // Reads what is there within the timeout; false once the peer has closed (or an error).
  bool receive(std::string* into) {
    char chunk[16384];
    const ssize_t n = ::recv(fd_, chunk, sizeof chunk, 0);
    if (n > 0) {
      into->append(chunk, static_cast<size_t>(n));
      return true;
    }
    return n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK);
  }

 private:
  int fd_ = -1;
};

// A client frame (RFC 6455 Sect. 5.2): FIN, the opcode, masked with the key 0 (allowed; the
// payload is then sent as is); `announced` (default: the payload's size) may be larger than the
// payload given.
std::string ws_frame(uint8_t opcode, std::string_view payload, uint64_t announced = UINT64_MAX) {
  if (announced == UINT64_MAX) announced = payload.size();
  std::string f;
  f.push_back(static_cast<char>(0x80 | opcode));
  if (announced < 126) {
    f.push_back(static_cast<char>(0x80 | announced));
  } else if (announced <= 0xFFFF) {
    f.push_back(static_cast<char>(0x80 | 126));
    f.push_back(static_cast<char>(announced >> 8));
    f.push_back(static_cast<char>(announced & 0xFF));
  } else {
    f.push_back(static_cast<char>(0x80 | 127));
    for (int i = 7; i >= 0; --i) f.push_back(static_cast<char>((announced >> (8 * i)) & 0xFF));
  }
  f.append(4, '\0');
  f.append(payload);
  return f;
}

bool ws_open(Tcp& t, int port, const std::atomic<bool>& stop, uint64_t* bytes) {
  if (!t.connect(port)) return false;
  const std::string req = "GET /websocket HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(port) +
                          "\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                          "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                          "Sec-WebSocket-Version: 13\r\n\r\n";
  if (!t.send(req, stop, bytes)) return false;
  std::string in;
  for (int i = 0; i < 25 && in.find("\r\n\r\n") == std::string::npos; ++i)
    if (!t.receive(&in)) return false;
  return in.rfind("HTTP/1.1 101", 0) == 0;
}

struct WebLoader {
  const char* kind = "";
  uint64_t connections = 0;  // opened
  uint64_t refused = 0;      // could not connect or upgrade (e.g. over the connection limit)
  uint64_t dropped = 0;      // the server closed the connection on us
  uint64_t bytes_sent = 0, replies = 0;
};

// One hostile client; its kind is `index % 5`.
void web_loop(int port, int index, const std::atomic<bool>& stop, WebLoader& w) {
  const auto stopped = [&] { return stop.load(std::memory_order_relaxed); };
  switch (index % 5) {
    case 0: {  // slow reader: 400 full object queries (a few MB of replies), never read
      w.kind = "slow reader";
      const std::string frame = ws_frame(
          1,
          R"({"jsonrpc":"2.0","method":"printer.objects.query","params":{"objects":{"toolhead":null,"configfile":null,"gcode":null,"feedloop_servo":null,"feedloop_tracking":null}},"id":1})");
      while (!stopped()) {
        Tcp t;
        t.small_receive_buffer();
        if (!ws_open(t, port, stop, &w.bytes_sent)) {
          ++w.refused;
          std::this_thread::sleep_for(std::chrono::milliseconds(100));
          continue;
        }
        ++w.connections;
        bool alive = true;
        for (int i = 0; i < 400 && alive && !stopped(); ++i)
          alive = t.send(frame, stop, &w.bytes_sent);
        // Hold it without reading until the server gives up on us (or the run ends).
        while (alive && !stopped()) {
          std::this_thread::sleep_for(std::chrono::milliseconds(200));
          alive = t.send(ws_frame(9, ""), stop, &w.bytes_sent);  // a ping now and then
        }
        if (!stopped()) ++w.dropped;
      }
      return;
    }
    case 1: {  // a frame that announces 64 MiB, sent until the server closes
      w.kind = "huge frame";
      const std::string chunk(64 * 1024, 'x');
      while (!stopped()) {
        Tcp t;
        if (!ws_open(t, port, stop, &w.bytes_sent)) {
          ++w.refused;
          std::this_thread::sleep_for(std::chrono::milliseconds(100));
          continue;
        }
        ++w.connections;
        bool alive = t.send(ws_frame(1, "", 64ull << 20), stop, &w.bytes_sent);
        while (alive && !stopped()) alive = t.send(chunk, stop, &w.bytes_sent);
        if (!stopped()) ++w.dropped;
      }
      return;
    }
    case 2: {  // many connections, each half a request header (slow loris), held 2 s
      w.kind = "many connections";
      while (!stopped()) {
        std::vector<std::unique_ptr<Tcp>> held;
        for (int i = 0; i < 40 && !stopped(); ++i) {
          auto t = std::make_unique<Tcp>();
          if (!t->connect(port)) {
            ++w.refused;
            continue;
          }
          ++w.connections;
          t->send("GET /server/info HTTP/1.1\r\nHost: x\r\nX-Slow: ", stop, &w.bytes_sent);
          held.push_back(std::move(t));
        }
        for (int i = 0; i < 10 && !stopped(); ++i)
          std::this_thread::sleep_for(std::chrono::milliseconds(200));
      }
      return;
    }
    case 3: {  // malformed: garbage HTTP, then a WebSocket with a reserved opcode and bad JSON
      w.kind = "malformed";
      uint32_t seed = 12345u + static_cast<uint32_t>(index);
      while (!stopped()) {
        Tcp t;
        if (t.connect(port)) {
          ++w.connections;
          std::string junk(512, '\0');
          for (char& c : junk) c = static_cast<char>((seed = seed * 1664525u + 1013904223u) >> 24);
          t.send(junk + "\r\n\r\n", stop, &w.bytes_sent);
          std::string in;
          t.receive(&in);
        } else {
          ++w.refused;
        }
        Tcp u;
        if (ws_open(u, port, stop, &w.bytes_sent)) {
          ++w.connections;
          u.send(ws_frame(1, "{\"jsonrpc\":\"2.0\",\"method\":"), stop, &w.bytes_sent);
          u.send(ws_frame(1, "[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[["), stop, &w.bytes_sent);
          u.send(ws_frame(3, "reserved opcode"), stop, &w.bytes_sent);
          std::string in;
          for (int k = 0; k < 10 && u.receive(&in) && !stopped(); ++k) {
          }
        } else {
          ++w.refused;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
      return;
    }
    default: {  // an HTTP flood of ordinary queries, each answer read
      w.kind = "http flood";
      while (!stopped()) {
        Tcp t;
        if (!t.connect(port)) {
          ++w.refused;
          std::this_thread::sleep_for(std::chrono::milliseconds(50));
          continue;
        }
        ++w.connections;
        for (int i = 0; i < 100 && !stopped(); ++i) {
          if (!t.send("GET /printer/objects/query?toolhead&extruder&print_stats HTTP/1.1\r\n"
                      "Host: x\r\n\r\n",
                      stop, &w.bytes_sent))
            break;
          std::string in;
          bool alive = true;
          for (int k = 0; k < 25 && alive && in.find("\"result\"") == std::string::npos; ++k)
            alive = t.receive(&in);
          if (!alive) break;
          ++w.replies;
        }
      }
      return;
    }
  }
}

// A free TCP port on 127.0.0.1 (bound and released; the daemon takes it right after).
int free_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t n = sizeof a;
  int port = 0;
  if (::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0 &&
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &n) == 0)
    port = ntohs(a.sin_port);
  ::close(fd);
  return port;
}

// The G-code to stream: comments and blank lines dropped, heater waits turned into set-points.
std::vector<std::string> load_program(const std::string& path, std::string* error) {
  std::ifstream f(path);
  if (!f) {
    *error = "cannot open " + path + " (run from the repository root, or pass --file)";
    return {};
  }
  std::vector<std::string> out;
  std::string line;
  while (std::getline(f, line)) {
    if (const size_t c = line.find(';'); c != std::string::npos) line.erase(c);
    while (!line.empty() && (line.back() == ' ' || line.back() == '\r' || line.back() == '\t'))
      line.pop_back();
    if (line.empty()) continue;
    if (line.rfind("M109", 0) == 0) line.replace(0, 4, "M104");
    if (line.rfind("M190", 0) == 0) line.replace(0, 4, "M140");
    out.push_back(line);
  }
  return out;
}

struct StreamResult {
  uint64_t sent = 0, oks = 0, errors = 0;
  std::vector<std::string> first_errors;
  bool ok = false;
  std::string error;
};

// A Marlin host: up to 4 lines without an `ok`; stops sending after `seconds` (0: never).
StreamResult stream(const std::string& sock, const std::vector<std::string>& lines,
                    double seconds) {
  StreamResult r;
  Conn c;
  if (!c.connect(sock, 5.0)) {
    r.error = "cannot connect to " + sock;
    return r;
  }
  const auto t0 = Clock::now();
  size_t next = 0, in_flight = 0;
  for (;;) {
    const bool sending = next < lines.size() && (seconds <= 0 || since_s(t0) < seconds);
    while (sending && in_flight < 4 && next < lines.size()) {
      if (!c.send(lines[next++] + "\n")) {
        r.error = "write failed";
        return r;
      }
      ++r.sent;
      ++in_flight;
    }
    if (in_flight == 0 && !(next < lines.size() && (seconds <= 0 || since_s(t0) < seconds))) break;
    // The machine takes tens of seconds of motion at once; an `ok` can be that far away (the
    // daemon's "echo:busy" keepalives come every 2 s meanwhile).
    auto reply = c.read_line(120.0);
    if (!reply) {
      r.error = "no reply from the G-code socket within 120 s";
      return r;
    }
    if (reply->rfind("Error:", 0) == 0) {
      ++r.errors;
      if (r.first_errors.size() < 3) r.first_errors.push_back(*reply);
    } else if (reply->rfind("ok", 0) == 0) {
      ++r.oks;
      if (in_flight > 0) --in_flight;
    }
  }
  r.ok = true;
  return r;
}

// CPU time (user + system) of a process, or of one of its threads.
double cpu_s_of(pid_t pid, pid_t tid = 0) {
  std::ifstream f("/proc/" + std::to_string(pid) +
                  (tid ? "/task/" + std::to_string(tid) : std::string()) + "/stat");
  std::string s((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  const size_t rp = s.rfind(')');
  if (rp == std::string::npos) return 0;
  std::istringstream in(s.substr(rp + 2));
  std::string field;
  unsigned long long utime = 0, stime = 0;
  for (int i = 3; i <= 15 && in >> field; ++i) {
    if (i == 14) utime = std::stoull(field);
    if (i == 15) stime = std::stoull(field);
  }
  return static_cast<double>(utime + stime) / static_cast<double>(::sysconf(_SC_CLK_TCK));
}

struct Run {
  int clients = 0, rep = 0;
  bool ok = false;
  std::string error;
  bool sched_fifo = true;
  uint64_t deadline_misses = 0, cycles = 0, lost_steps = 0, late_cycles = 0, rejected = 0;
  uint64_t lines_sent = 0, error_replies = 0;
  std::string fault;  // the machine stopped with this error
  double p99_us = 0, max_us = 0, print_s = 0, daemon_cpu_s = 0, io_cpu_s = 0;
  uint64_t replies = 0, failures = 0;
  int pollers_connected = 0;
  double reply_p50_ms = 0, reply_p99_ms = 0, reply_max_ms = 0;
  double e_t_mean_um = 0, e_t_max_um = 0;  // tracking error from the encoders over the run
  // --load web: the hostile clients' totals.
  uint64_t web_connections = 0, web_refused = 0, web_dropped = 0, web_replies = 0;
  double web_sent_mb = 0;
  std::vector<std::string> first_errors;
};

uint64_t u64(const json& j, const char* a, const char* b) {
  return j.at(a).at(b).get<uint64_t>();
}

Run run_once(const Args& a, const std::vector<std::string>& program, int clients, int rep) {
  Run r;
  r.clients = clients;
  r.rep = rep;
  std::string tmpl =
      (std::filesystem::temp_directory_path() / "feedloop-bench-clients-XXXXXX").string();
  if (::mkdtemp(tmpl.data()) == nullptr) {
    r.error = "mkdtemp failed";
    return r;
  }
  const std::string dir = tmpl;
  const std::string log = dir + "/feedloopd.log";
  const std::string config = dir + "/printer.yaml";
  const bool own_config = a.priority >= 0 || a.web;
  const int web_port = a.web ? free_port() : 0;
  if (own_config) {
    // The embedded default with another servo priority (0: a user without CAP_SYS_NICE) and/or
    // the web server on (--load web; on in both conditions, so only the clients differ).
    feedloop::config::MachineConfig cfg = feedloop::config::default_config();
    if (a.priority >= 0) cfg.servo.realtime_priority = a.priority;
    if (a.web) {
      cfg.web.enabled = true;
      cfg.web.port = web_port;
    }
    std::ofstream(config) << feedloop::config::to_yaml(cfg);
  }
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(fd, 1);
    ::dup2(fd, 2);
    ::setenv("RUNTIME_DIRECTORY", dir.c_str(), 1);
    ::setenv("STATE_DIRECTORY", dir.c_str(), 1);
    if (own_config)
      ::execl(a.feedloopd.c_str(), a.feedloopd.c_str(), "--log-level", "info", "--config",
              config.c_str(), static_cast<char*>(nullptr));
    else
      ::execl(a.feedloopd.c_str(), a.feedloopd.c_str(), "--log-level", "info",
              static_cast<char*>(nullptr));
    ::_exit(127);
  }
  auto finish = [&] {
    ::kill(pid, SIGTERM);
    for (int i = 0; i < 500; ++i) {
      if (::waitpid(pid, nullptr, WNOHANG) == pid) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      if (i == 499) {
        ::kill(pid, SIGKILL);
        ::waitpid(pid, nullptr, 0);
      }
    }
    std::ifstream f(log);
    std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    r.sched_fifo = text.find("SCHED_FIFO") == std::string::npos;
    std::error_code ec;
    if (r.ok)
      std::filesystem::remove_all(dir, ec);
    else
      r.error += " (daemon log kept: " + log + ")";
  };
  const std::string api = dir + "/api.sock", sock = dir + "/feedloop.sock";
  Conn control;
  if (!control.connect(api, 10.0)) {
    r.error = "feedloopd did not open " + api;
    finish();
    return r;
  }
  std::atomic<bool> stop{false};
  std::vector<Poller> pollers(static_cast<size_t>(clients));
  std::vector<WebLoader> loaders(static_cast<size_t>(a.web ? clients : 0));
  std::vector<std::thread> threads;
  for (int i = 0; i < clients; ++i) {
    if (a.web)
      threads.emplace_back(web_loop, web_port, i, std::cref(stop),
                           std::ref(loaders[static_cast<size_t>(i)]));
    else
      threads.emplace_back(poll_loop, api, a.poll_ms, std::cref(stop),
                           std::ref(pollers[static_cast<size_t>(i)]));
  }
  std::this_thread::sleep_for(
      std::chrono::milliseconds(1000));  // every poller connected and polling
  const auto s0 = request_status(control, 1);
  const double cpu0 = cpu_s_of(pid);
  const double io0 = cpu_s_of(pid, pid);  // the main thread is the daemon's I/O thread
  const auto t0 = Clock::now();
  StreamResult sr = stream(sock, program, a.seconds);
  // The queued motion runs out.
  std::optional<json> s1;
  for (int i = 0; sr.ok && i < 1200; ++i) {
    s1 = request_status(control, 2 + i);
    if (!s1 || s1->at("state") == "error" ||
        (s1->at("state") == "idle" && s1->at("queue").at("depth") == 0))
      break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  r.print_s = since_s(t0);
  r.daemon_cpu_s = cpu_s_of(pid) - cpu0;
  r.io_cpu_s = cpu_s_of(pid, pid) - io0;
  stop.store(true);
  for (auto& t : threads) t.join();
  finish();
  if (!sr.ok || !s0 || !s1) {
    r.error = !sr.ok ? sr.error : "no status from the JSON API";
    return r;
  }
  try {
    r.deadline_misses = u64(*s1, "servo", "deadline_misses") - u64(*s0, "servo", "deadline_misses");
    r.cycles = u64(*s1, "servo", "cycles") - u64(*s0, "servo", "cycles");
    r.lost_steps = u64(*s1, "motion", "lost_step_events") - u64(*s0, "motion", "lost_step_events");
    r.late_cycles = u64(*s1, "motion", "late_cycles") - u64(*s0, "motion", "late_cycles");
    r.rejected = u64(*s1, "commands", "rejected") - u64(*s0, "commands", "rejected");
    if (s1->at("state") == "error") r.fault = s1->at("last_error").get<std::string>();
    r.e_t_mean_um = 1000.0 * s1->at("motion").at("tracking_error_mm").at("mean").get<double>();
    r.e_t_max_um = 1000.0 * s1->at("motion").at("tracking_error_mm").at("max").get<double>();
    r.p99_us = s1->at("servo").at("latency_us").at("p99").get<double>();
    r.max_us = s1->at("servo").at("latency_us").at("max").get<double>();
  } catch (const json::exception& e) {
    r.error = std::string("unexpected status: ") + e.what();
    return r;
  }
  r.lines_sent = sr.sent;
  r.error_replies = sr.errors;
  r.first_errors = sr.first_errors;
  for (const WebLoader& w : loaders) {
    r.web_connections += w.connections;
    r.web_refused += w.refused;
    r.web_dropped += w.dropped;
    r.web_replies += w.replies;
    r.web_sent_mb += static_cast<double>(w.bytes_sent) / 1e6;
  }
  std::vector<float> all;
  for (const Poller& p : pollers) {
    r.replies += p.replies;
    r.failures += p.failures;
    r.pollers_connected += p.connected ? 1 : 0;
    all.insert(all.end(), p.rtt_us.begin(), p.rtt_us.end());
  }
  if (!all.empty()) {
    std::sort(all.begin(), all.end());
    auto pct = [&](double q) {
      return all[std::min(all.size() - 1,
                          static_cast<size_t>(q * static_cast<double>(all.size())))] /
             1000.0;
    };
    r.reply_p50_ms = pct(0.50);
    r.reply_p99_ms = pct(0.99);
    r.reply_max_ms = all.back() / 1000.0;
  }
  r.ok = true;
  return r;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

json to_json(const Run& r) {
  return {{"clients", r.clients},
          {"rep", r.rep},
          {"ok", r.ok},
          {"error", r.error},
          {"fault", r.fault},
          {"sched_fifo", r.sched_fifo},
          {"seconds", r.print_s},
          {"servo_cycles", r.cycles},
          {"deadline_misses", r.deadline_misses},
          {"latency_p99_us", r.p99_us},
          {"latency_max_us", r.max_us},
          {"lost_step_events", r.lost_steps},
          {"late_cycles", r.late_cycles},
          {"rejected_commands", r.rejected},
          {"lines_sent", r.lines_sent},
          {"error_replies", r.error_replies},
          {"status_replies", r.replies},
          {"poll_failures", r.failures},
          {"pollers_connected", r.pollers_connected},
          {"reply_p50_ms", r.reply_p50_ms},
          {"reply_p99_ms", r.reply_p99_ms},
          {"reply_max_ms", r.reply_max_ms},
          {"e_t_mean_um", r.e_t_mean_um},
          {"e_t_max_um", r.e_t_max_um},
          {"web_connections", r.web_connections},
          {"web_refused", r.web_refused},
          {"web_dropped", r.web_dropped},
          {"web_replies", r.web_replies},
          {"web_sent_mb", r.web_sent_mb},
          {"daemon_cpu_s", r.daemon_cpu_s},
          {"io_thread_cpu_s", r.io_cpu_s}};
}

int usage() {
  std::fprintf(
      stderr,
      "usage: bench_clients [--clients N] [--poll-ms P] [--reps R] [--seconds S] [--file GCODE]\n"
      "                     [--load json|web] [--priority PRIO] [--feedloopd PATH] [--json "
      "FILE]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    const bool has = i + 1 < argc;
    if (k == "--clients" && has)
      a.clients = std::atoi(argv[++i]);
    else if (k == "--poll-ms" && has)
      a.poll_ms = std::atof(argv[++i]);
    else if (k == "--reps" && has)
      a.reps = std::atoi(argv[++i]);
    else if (k == "--seconds" && has)
      a.seconds = std::atof(argv[++i]);
    else if (k == "--file" && has)
      a.file = argv[++i];
    else if (k == "--feedloopd" && has)
      a.feedloopd = argv[++i];
    else if (k == "--json" && has)
      a.json_path = argv[++i];
    else if (k == "--priority" && has)
      a.priority = std::atoi(argv[++i]);
    else if (k == "--load" && has &&
             (std::string(argv[i + 1]) == "json" || std::string(argv[i + 1]) == "web"))
      a.web = std::string(argv[++i]) == "web";
    else
      return usage();
  }
  if (a.clients < 1 || a.clients > 1000 || a.reps < 1 || !(a.poll_ms >= 1.0) || a.seconds < 0)
    return usage();
  std::string error;
  const std::vector<std::string> program = load_program(a.file, &error);
  if (program.empty()) {
    std::fprintf(stderr, "bench_clients: %s\n", error.empty() ? "empty program" : error.c_str());
    return 1;
  }
  const std::string streaming =
      a.seconds > 0 ? "streaming stops after " + std::to_string(static_cast<int>(a.seconds)) + " s"
                    : std::string("whole file");
  if (a.web)
    std::printf(
        "bench_clients: %s (%zu lines, %s), web server on, 0 vs %d hostile web clients (slow "
        "readers, 64 MiB frames, slow-loris connections, malformed input, HTTP flood), %d reps "
        "each\n",
        a.file.c_str(), program.size(), streaming.c_str(), a.clients, a.reps);
  else
    std::printf(
        "bench_clients: %s (%zu lines, %s), 0 vs %d clients polling status every %.0f ms, %d "
        "reps each\n",
        a.file.c_str(), program.size(), streaming.c_str(), a.clients, a.poll_ms, a.reps);
  std::printf("%-8s %3s %7s %7s %7s %9s %9s %5s %5s %8s %8s %9s %8s %8s %7s %7s %8s %8s\n",
              "clients", "rep", "time_s", "cycles", "misses", "p99_us", "max_us", "lost", "late",
              "rejected", "err_rep", "replies/s", "rtt_p50", "rtt_p99", "cpu_s", "io_cpu",
              "e_t_mean", "e_t_max");
  std::vector<Run> runs;
  for (int rep = 0; rep < a.reps; ++rep) {
    // A B, then B A: interleaved so that a slow stretch of the shared machine hits both.
    const int order[2] = {rep % 2 == 0 ? 0 : a.clients, rep % 2 == 0 ? a.clients : 0};
    for (const int n : order) {
      Run r = run_once(a, program, n, rep + 1);
      if (!r.ok) {
        std::printf("%-8d %3d  FAILED: %s\n", n, rep + 1, r.error.c_str());
      } else {
        std::printf(
            "%-8d %3d %7.1f %7llu %7llu %9.1f %9.1f %5llu %5llu %8llu %8llu %9.0f %8.2f %8.2f "
            "%7.2f %7.2f %8.2f %8.2f%s\n",
            n, rep + 1, r.print_s, static_cast<unsigned long long>(r.cycles),
            static_cast<unsigned long long>(r.deadline_misses), r.p99_us, r.max_us,
            static_cast<unsigned long long>(r.lost_steps),
            static_cast<unsigned long long>(r.late_cycles),
            static_cast<unsigned long long>(r.rejected),
            static_cast<unsigned long long>(r.error_replies),
            static_cast<double>(a.web ? r.web_replies : r.replies) / r.print_s, r.reply_p50_ms,
            r.reply_p99_ms, r.daemon_cpu_s, r.io_cpu_s, r.e_t_mean_um, r.e_t_max_um,
            r.sched_fifo ? "" : "  (no SCHED_FIFO)");
        if (a.web && n > 0)
          std::printf(
              "         web: %llu connections, %llu refused, %llu dropped by the server, %.1f MB "
              "sent, %llu HTTP replies\n",
              static_cast<unsigned long long>(r.web_connections),
              static_cast<unsigned long long>(r.web_refused),
              static_cast<unsigned long long>(r.web_dropped), r.web_sent_mb,
              static_cast<unsigned long long>(r.web_replies));
        if (!r.fault.empty()) std::printf("         machine fault: %s\n", r.fault.c_str());
        for (const std::string& e : r.first_errors)
          std::printf("         error reply: %s\n", e.c_str());
        if (!a.web && n > 0 && (r.pollers_connected < n || r.failures > 0))
          std::printf("         pollers connected %d of %d, failed requests %llu\n",
                      r.pollers_connected, n, static_cast<unsigned long long>(r.failures));
      }
      std::fflush(stdout);
      runs.push_back(std::move(r));
    }
  }
  std::printf("\nmedian [min..max] of %d reps   %17s %26s\n", a.reps, "0 clients",
              (std::to_string(a.clients) + " clients").c_str());
  json summary = json::object();
  // Median and range of each condition: the two are the same within noise where the ranges
  // overlap.
  auto row = [&](const char* name, auto field, const char* fmt) {
    std::string cell[2];
    json j[2];
    for (int k = 0; k < 2; ++k) {
      std::vector<double> v;
      for (const Run& r : runs)
        if (r.ok && (r.clients > 0) == (k == 1)) v.push_back(static_cast<double>(field(r)));
      if (v.empty()) continue;
      const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
      char med[32], lo_text[32], hi_text[32];
      std::snprintf(med, sizeof med, fmt, median(v));
      std::snprintf(lo_text, sizeof lo_text, fmt, *lo);
      std::snprintf(hi_text, sizeof hi_text, fmt, *hi);
      cell[k] = std::string(med) + " [" + lo_text + ".." + hi_text + "]";
      j[k] = {{"median", median(v)}, {"min", *lo}, {"max", *hi}};
    }
    std::printf("%-20s %26s %26s\n", name, cell[0].c_str(), cell[1].c_str());
    summary[name] = {{"no_clients", j[0]}, {"clients", j[1]}};
  };
  row(
      "machine_faults", [](const Run& r) { return r.fault.empty() ? 0 : 1; }, "%.0f");
  row(
      "deadline_misses", [](const Run& r) { return r.deadline_misses; }, "%.0f");
  row(
      "misses_per_1e5",
      [](const Run& r) {
        return r.cycles
                   ? 1e5 * static_cast<double>(r.deadline_misses) / static_cast<double>(r.cycles)
                   : 0.0;
      },
      "%.1f");
  row(
      "latency_p99_us", [](const Run& r) { return r.p99_us; }, "%.1f");
  row(
      "latency_max_us", [](const Run& r) { return r.max_us; }, "%.0f");
  row(
      "e_t_mean_um", [](const Run& r) { return r.e_t_mean_um; }, "%.2f");
  row(
      "e_t_max_um", [](const Run& r) { return r.e_t_max_um; }, "%.1f");
  row(
      "lost_step_events", [](const Run& r) { return r.lost_steps; }, "%.0f");
  row(
      "late_cycles", [](const Run& r) { return r.late_cycles; }, "%.0f");
  row(
      "rejected_commands", [](const Run& r) { return r.rejected; }, "%.0f");
  row(
      "error_replies", [](const Run& r) { return r.error_replies; }, "%.0f");
  row(
      a.web ? "http_replies_per_s" : "status_replies_per_s",
      [&a](const Run& r) {
        return static_cast<double>(a.web ? r.web_replies : r.replies) / r.print_s;
      },
      "%.0f");
  if (a.web) {
    row(
        "web_connections", [](const Run& r) { return r.web_connections; }, "%.0f");
    row(
        "web_dropped", [](const Run& r) { return r.web_dropped; }, "%.0f");
    row(
        "web_sent_mb", [](const Run& r) { return r.web_sent_mb; }, "%.0f");
  }
  row(
      "reply_p99_ms", [](const Run& r) { return r.reply_p99_ms; }, "%.2f");
  row(
      "daemon_cpu_s", [](const Run& r) { return r.daemon_cpu_s; }, "%.2f");
  if (!a.json_path.empty()) {
    json out = {{"bench", "clients"},   {"file", a.file},
                {"clients", a.clients}, {"load", a.web ? "web" : "json"},
                {"poll_ms", a.poll_ms}, {"reps", a.reps},
                {"seconds", a.seconds}, {"runs", json::array()},
                {"median", summary}};
    for (const Run& r : runs) out["runs"].push_back(to_json(r));
    if (!feedloop::bench::write_json(a.json_path, out)) return 1;
  }
  for (const Run& r : runs)
    if (!r.ok) return 1;
  return 0;
}
