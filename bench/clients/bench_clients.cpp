// bench_clients: does client I/O delay the machine? A real-time print on feedloopd's embedded
// simulated printer, once with no clients and once with N clients polling JSON `status` every
// P ms (defaults: 50 clients, 10 ms), several repetitions each, interleaved (A B B A ...: the
// machine is shared and noisy, so drift falls on both conditions alike). Per run it prints the
// servo loop's deadline misses, wake-up latency p99/max, lost-step events, late cycles and
// rejected lines, the pollers' reply round trips, and the daemon's CPU time; then the median of
// each condition side by side.
//
// Each run starts a fresh feedloopd (the binary, as users run it: SCHED_FIFO and mlockall when
// permitted) with its runtime and state directories in a temporary directory, streams the G-code
// file through feedloop.sock as a Marlin host (window of 4 lines, like `feedloop print`) with
// heater waits (M109/M190) sent as plain set-points (the bench measures motion, not heating),
// stops sending after --seconds of streaming (0: the whole file), waits for the machine to go
// idle, and reads the counters through the JSON API before and after.
//
//   build/bench/clients/bench_clients [--clients 50] [--poll-ms 10] [--reps 3] [--seconds 30]
//        [--file examples/gcode/cube20_3layers.gcode] [--feedloopd PATH] [--json FILE]
#include <fcntl.h>       // open
#include <poll.h>        // poll
#include <signal.h>      // kill
#include <sys/socket.h>  // socket
#include <sys/un.h>      // sockaddr_un
#include <sys/wait.h>    // waitpid
#include <unistd.h>      // fork, execv

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "config/config.hpp"

namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

struct Args {
  int clients = 50;
  double poll_ms = 10.0;
  int reps = 3;
  double seconds = 30.0;
  std::string file = "examples/gcode/cube20_3layers.gcode";
  std::string feedloopd = FEEDLOOPD_PATH;
  std::string json_path;
  int priority = -1;  // the servo thread's SCHED_FIFO priority; -1: the config's (80), 0: none
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
    auto reply = c.read_line(60.0);
    if (!reply) {
      r.error = "no reply from the G-code socket within 60 s";
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

double cpu_s_of(pid_t pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/stat");
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
  double p99_us = 0, max_us = 0, print_s = 0, daemon_cpu_s = 0;
  uint64_t replies = 0, failures = 0;
  int pollers_connected = 0;
  double reply_p50_ms = 0, reply_p99_ms = 0, reply_max_ms = 0;
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
  if (a.priority >= 0) {
    // The embedded default with another servo priority (0: a user without CAP_SYS_NICE).
    feedloop::config::MachineConfig cfg = feedloop::config::default_config();
    cfg.servo.realtime_priority = a.priority;
    std::ofstream(config) << feedloop::config::to_yaml(cfg);
  }
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(fd, 1);
    ::dup2(fd, 2);
    ::setenv("RUNTIME_DIRECTORY", dir.c_str(), 1);
    ::setenv("STATE_DIRECTORY", dir.c_str(), 1);
    if (a.priority >= 0)
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
    std::filesystem::remove_all(dir, ec);
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
  std::vector<std::thread> threads;
  for (int i = 0; i < clients; ++i)
    threads.emplace_back(poll_loop, api, a.poll_ms, std::cref(stop),
                         std::ref(pollers[static_cast<size_t>(i)]));
  std::this_thread::sleep_for(
      std::chrono::milliseconds(1000));  // every poller connected and polling
  const auto s0 = request_status(control, 1);
  const double cpu0 = cpu_s_of(pid);
  const auto t0 = Clock::now();
  StreamResult sr = stream(sock, program, a.seconds);
  // The queued motion runs out.
  std::optional<json> s1;
  for (int i = 0; sr.ok && i < 1200; ++i) {
    s1 = request_status(control, 2 + i);
    if (!s1 || (s1->at("state") == "idle" && s1->at("queue").at("depth") == 0)) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  r.print_s = since_s(t0);
  r.daemon_cpu_s = cpu_s_of(pid) - cpu0;
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
    r.p99_us = s1->at("servo").at("latency_us").at("p99").get<double>();
    r.max_us = s1->at("servo").at("latency_us").at("max").get<double>();
  } catch (const json::exception& e) {
    r.error = std::string("unexpected status: ") + e.what();
    return r;
  }
  r.lines_sent = sr.sent;
  r.error_replies = sr.errors;
  r.first_errors = sr.first_errors;
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
          {"daemon_cpu_s", r.daemon_cpu_s}};
}

int usage() {
  std::fprintf(
      stderr,
      "usage: bench_clients [--clients N] [--poll-ms P] [--reps R] [--seconds S] [--file GCODE]\n"
      "                     [--priority PRIO] [--feedloopd PATH] [--json FILE]\n");
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
  std::printf(
      "bench_clients: %s (%zu lines, %s), 0 vs %d clients polling status every %.0f ms, %d reps "
      "each\n",
      a.file.c_str(), program.size(),
      a.seconds > 0
          ? ("streaming stops after " + std::to_string(static_cast<int>(a.seconds)) + " s").c_str()
          : "whole file",
      a.clients, a.poll_ms, a.reps);
  std::printf("%-8s %3s %7s %7s %7s %9s %9s %5s %5s %8s %8s %9s %8s %8s %7s\n", "clients", "rep",
              "time_s", "cycles", "misses", "p99_us", "max_us", "lost", "late", "rejected",
              "err_rep", "replies/s", "rtt_p50", "rtt_p99", "cpu_s");
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
            "%7.2f%s\n",
            n, rep + 1, r.print_s, static_cast<unsigned long long>(r.cycles),
            static_cast<unsigned long long>(r.deadline_misses), r.p99_us, r.max_us,
            static_cast<unsigned long long>(r.lost_steps),
            static_cast<unsigned long long>(r.late_cycles),
            static_cast<unsigned long long>(r.rejected),
            static_cast<unsigned long long>(r.error_replies),
            static_cast<double>(r.replies) / r.print_s, r.reply_p50_ms, r.reply_p99_ms,
            r.daemon_cpu_s, r.sched_fifo ? "" : "  (no SCHED_FIFO)");
        for (const std::string& e : r.first_errors)
          std::printf("         error reply: %s\n", e.c_str());
        if (n > 0 && (r.pollers_connected < n || r.failures > 0))
          std::printf("         pollers connected %d of %d, failed requests %llu\n",
                      r.pollers_connected, n, static_cast<unsigned long long>(r.failures));
      }
      std::fflush(stdout);
      runs.push_back(std::move(r));
    }
  }
  std::printf("\nmedian of %d reps    %12s %12s\n", a.reps, "0 clients",
              (std::to_string(a.clients) + " clients").c_str());
  json summary = json::object();
  auto row = [&](const char* name, auto field, const char* fmt) {
    double m[2];
    for (int k = 0; k < 2; ++k) {
      std::vector<double> v;
      for (const Run& r : runs)
        if (r.ok && (r.clients > 0) == (k == 1)) v.push_back(static_cast<double>(field(r)));
      m[k] = median(v);
    }
    char b0[32], b1[32];
    std::snprintf(b0, sizeof b0, fmt, m[0]);
    std::snprintf(b1, sizeof b1, fmt, m[1]);
    std::printf("%-20s %12s %12s\n", name, b0, b1);
    summary[name] = {{"no_clients", m[0]}, {"clients", m[1]}};
  };
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
      "lost_step_events", [](const Run& r) { return r.lost_steps; }, "%.0f");
  row(
      "late_cycles", [](const Run& r) { return r.late_cycles; }, "%.0f");
  row(
      "rejected_commands", [](const Run& r) { return r.rejected; }, "%.0f");
  row(
      "error_replies", [](const Run& r) { return r.error_replies; }, "%.0f");
  row(
      "status_replies_per_s",
      [](const Run& r) { return static_cast<double>(r.replies) / r.print_s; }, "%.0f");
  row(
      "reply_p99_ms", [](const Run& r) { return r.reply_p99_ms; }, "%.2f");
  row(
      "daemon_cpu_s", [](const Run& r) { return r.daemon_cpu_s; }, "%.2f");
  if (!a.json_path.empty()) {
    json out = {{"bench", "clients"},    {"file", a.file},   {"clients", a.clients},
                {"poll_ms", a.poll_ms},  {"reps", a.reps},   {"seconds", a.seconds},
                {"runs", json::array()}, {"median", summary}};
    for (const Run& r : runs) out["runs"].push_back(to_json(r));
    std::ofstream(a.json_path) << out.dump(2) << "\n";
  }
  for (const Run& r : runs)
    if (!r.ok) return 1;
  return 0;
}
