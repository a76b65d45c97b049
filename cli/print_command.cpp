#include "cli/print_command.hpp"

#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <deque>
#include <fstream>
#include <optional>
#include <string>

#include "cli/progress.hpp"
#include "config/config.hpp"
#include "gcode/host_protocol.hpp"
#include "gcode/line_splitter.hpp"

namespace feedloop::cli {
namespace {

// A blocking line connection to a Unix socket.
class Connection {
 public:
  ~Connection() {
    if (fd_ >= 0) ::close(fd_);
  }
  bool open(const std::string& path) {
    fd_ = ::socket(AF_UNIX, SOCK_STREAM, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", path.c_str());
    return ::connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
  }
  bool send(const std::string& s) {
    for (size_t off = 0; off < s.size();) {
      const ssize_t n = ::write(fd_, s.data() + off, s.size() - off);
      if (n <= 0) return false;
      off += static_cast<size_t>(n);
    }
    return true;
  }
  // Next line or nullopt after timeout_ms / on close. `closed` tells which.
  std::optional<std::string> read_line(int timeout_ms, bool* closed = nullptr) {
    for (;;) {
      if (const size_t nl = buf_.find('\n'); nl != std::string::npos) {
        std::string line = buf_.substr(0, nl);
        buf_.erase(0, nl + 1);
        return line;
      }
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, timeout_ms) <= 0) return std::nullopt;
      char tmp[8192];
      const ssize_t n = ::read(fd_, tmp, sizeof tmp);
      if (n <= 0) {
        if (closed) *closed = true;
        return std::nullopt;
      }
      buf_.append(tmp, static_cast<size_t>(n));
    }
  }

 private:
  int fd_ = -1;
  std::string buf_;
};

struct Sent {
  int64_t n;
  int file_line;
  std::string text;  // the full "N.. cmd*cs" line
};

std::string numbered_line(int64_t n, std::string_view cmd) {
  std::string s = "N" + std::to_string(n) + " ";
  s.append(cmd);
  s += "*" + std::to_string(gcode::HostProtocol::checksum(s));
  return s;
}

std::string_view strip_comment(std::string_view line) {
  line = line.substr(0, line.find(';'));
  while (!line.empty() && (line.back() == ' ' || line.back() == '\t' || line.back() == '\r'))
    line.remove_suffix(1);
  while (!line.empty() && (line.front() == ' ' || line.front() == '\t')) line.remove_prefix(1);
  return line;
}

void usage() {
  std::fputs(
      "usage: feedloop print FILE [--socket PATH] [--api PATH] [--window N]\n"
      "  Streams FILE to a running feedloopd (Marlin host protocol with line numbers and\n"
      "  checksums, N lines in flight, default 4) and prints a summary.\n"
      "  Default sockets: ${RUNTIME_DIR}/feedloop.sock and ${RUNTIME_DIR}/api.sock.\n",
      stderr);
}

}  // namespace

int print_command(const std::vector<std::string>& args) {
  std::string file, socket_path, api_path;
  size_t window = 4;
  for (size_t i = 0; i < args.size(); ++i) {
    if (args[i] == "--socket" && i + 1 < args.size()) socket_path = args[++i];
    else if (args[i] == "--api" && i + 1 < args.size()) api_path = args[++i];
    else if (args[i] == "--window" && i + 1 < args.size()) window = std::stoul(args[++i]);
    else if (args[i] == "--help") { usage(); return 0; }
    else if (file.empty() && args[i].rfind("--", 0) != 0) file = args[i];
    else { std::fprintf(stderr, "feedloop print: unexpected argument '%s'\n", args[i].c_str()); usage(); return 2; }
  }
  if (file.empty()) { usage(); return 2; }
  if (window < 1) window = 1;
  const config::PathVars vars = config::path_vars_from_environment();
  if (socket_path.empty()) socket_path = *config::expand_path("${RUNTIME_DIR}/feedloop.sock", vars);
  if (api_path.empty()) api_path = *config::expand_path("${RUNTIME_DIR}/api.sock", vars);

  std::ifstream in(file, std::ios::binary);
  if (!in) { std::fprintf(stderr, "feedloop print: cannot open %s\n", file.c_str()); return 1; }
  double total_lines = 0;  // for progress: physical lines of the file
  {
    char buf[65536];
    while (in.read(buf, sizeof buf) || in.gcount() > 0) {
      total_lines += static_cast<double>(std::count(buf, buf + in.gcount(), '\n'));
      if (in.gcount() < static_cast<std::streamsize>(sizeof buf)) break;
    }
    in.clear();
    in.seekg(0);
  }
  Connection conn;
  if (!conn.open(socket_path)) {
    std::fprintf(stderr, "feedloop print: cannot connect to %s: %s (is feedloopd running?)\n",
                 socket_path.c_str(), std::strerror(errno));
    return 1;
  }

  // Read the whole file's command lines lazily through the splitter.
  std::deque<Sent> in_flight;  // sent, not yet acknowledged (also the resend buffer)
  std::deque<Sent> to_send;
  int64_t next_n = 1, acked = 0, errors = 0, resends = 0, lines_sent = 0;
  gcode::LineSplitter splitter;
  std::vector<std::pair<int, std::string>> pending;  // (file line, command) from the last chunk
  char chunk[65536];
  int acked_file_line = 0;
  bool eof = false;
  Progress progress("printing " + file.substr(file.find_last_of('/') + 1));
  const auto t0 = std::chrono::steady_clock::now();

  conn.send("M110 N0\n");
  if (conn.read_line(5000) != std::optional<std::string>("ok")) {
    std::fprintf(stderr, "feedloop print: no answer from feedloopd on %s\n", socket_path.c_str());
    return 1;
  }
  auto refill = [&] {
    while (to_send.size() < 256 && !eof) {
      in.read(chunk, sizeof chunk);
      const std::streamsize got = in.gcount();
      auto on_line = [&](const gcode::SplitLine& l) {
        const std::string_view cmd = l.too_long ? std::string_view("G4 P0 ; too long") : strip_comment(l.text);
        if (cmd.empty()) return;
        to_send.push_back({next_n, static_cast<int>(l.number), numbered_line(next_n, cmd)});
        ++next_n;
      };
      splitter.feed(std::string_view(chunk, static_cast<size_t>(got)), on_line);
      if (got < static_cast<std::streamsize>(sizeof chunk)) {
        splitter.finish(on_line);
        eof = true;
      }
    }
  };
  refill();
  while (!to_send.empty() || !in_flight.empty()) {
    while (in_flight.size() < window && !to_send.empty()) {
      Sent s = std::move(to_send.front());
      to_send.pop_front();
      if (!conn.send(s.text + "\n")) { std::fprintf(stderr, "\nfeedloop print: connection lost\n"); return 1; }
      ++lines_sent;
      in_flight.push_back(std::move(s));
      refill();
    }
    bool closed = false;
    auto reply = conn.read_line(30000, &closed);
    if (!reply) {
      std::fprintf(stderr, "\nfeedloop print: %s\n",
                   closed ? "feedloopd closed the connection" : "no reply for 30 s; giving up");
      return 1;
    }
    if (*reply == "ok") {
      if (!in_flight.empty()) {
        acked_file_line = in_flight.front().file_line;
        in_flight.pop_front();
      }
      ++acked;
    } else if (reply->rfind("Resend: ", 0) == 0) {
      const int64_t n = std::stoll(reply->substr(8));
      ++resends;
      // Everything from n on goes again, in order; the ok that follows acknowledges nothing.
      while (!in_flight.empty() && in_flight.back().n >= n) {
        to_send.push_front(std::move(in_flight.back()));
        in_flight.pop_back();
      }
      conn.read_line(5000);  // the ok of the refused line
    } else if (reply->rfind("Error:", 0) == 0) {
      ++errors;
      const int file_line = in_flight.empty() ? 0 : in_flight.front().file_line;
      std::fprintf(stderr, "\n%s:%d: %s\n", file.c_str(), file_line, reply->c_str() + 6);
    }
    progress.update(total_lines > 0 ? std::min(1.0, acked_file_line / total_lines) : 1.0,
                    std::to_string(acked) + " lines acknowledged");
  }
  // The last lines are acknowledged when planned; M400 returns when the machine has finished.
  conn.send(numbered_line(next_n, "M400") + "\n");
  for (;;) {
    auto reply = conn.read_line(600000);
    if (!reply || *reply == "ok") break;
    if (reply->rfind("Error:", 0) == 0) { ++errors; std::fprintf(stderr, "\n%s\n", reply->c_str()); }
  }
  progress.update(1.0, std::to_string(acked) + " lines acknowledged, machine finished");
  progress.finish();
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  std::printf("\nprint summary: %s\n", file.c_str());
  std::printf("  lines sent        %lld (%lld acknowledged, %lld errors, %lld resends)\n",
              static_cast<long long>(lines_sent), static_cast<long long>(acked),
              static_cast<long long>(errors), static_cast<long long>(resends));
  std::printf("  wall time         %.2f s (%.0f lines/s)\n", wall_s, lines_sent / std::max(wall_s, 1e-9));
  Connection api;
  if (api.open(api_path) && api.send(R"({"jsonrpc":"2.0","id":1,"method":"status"})" "\n")) {
    if (auto line = api.read_line(5000)) {
      const auto st = nlohmann::json::parse(*line, nullptr, false);
      if (st.contains("result")) {
        const auto& r = st["result"];
        std::printf("  daemon            state %s, %llu commands executed, %llu rejected\n",
                    r["state"].get<std::string>().c_str(), r["commands"]["executed"].get<unsigned long long>(),
                    r["commands"]["rejected"].get<unsigned long long>());
        std::printf("  position          X %.3f Y %.3f Z %.3f E %.3f mm\n",
                    r["position_mm"]["x"].get<double>(), r["position_mm"]["y"].get<double>(),
                    r["position_mm"]["z"].get<double>(), r["position_mm"]["e"].get<double>());
        std::printf("  servo loop        %llu cycles, %llu deadline misses, wake-up latency p50 %.1f us, p99 %.1f us, max %.1f us\n",
                    r["servo"]["cycles"].get<unsigned long long>(),
                    r["servo"]["deadline_misses"].get<unsigned long long>(),
                    r["servo"]["latency_us"]["p50"].get<double>(), r["servo"]["latency_us"]["p99"].get<double>(),
                    r["servo"]["latency_us"]["max"].get<double>());
        if (r.contains("motion")) std::printf("  motion            %s\n", r["motion"].dump().c_str());
      }
    }
  }
  return errors == 0 ? 0 : 3;
}

}  // namespace feedloop::cli
