#include "cli/print_command.hpp"

#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <thread>

#include "cli/line_connection.hpp"
#include "cli/print_lines.hpp"
#include "cli/progress.hpp"
#include "config/config.hpp"
#include "gcode/file_kind.hpp"
#include "gcode/host_protocol.hpp"
#include "gcode/line_splitter.hpp"

namespace feedloop::cli {
namespace {

struct Sent {
  int64_t n;
  int file_line;
  std::string text;  // the full "N.. cmd*cs" line
};

void usage() {
  std::fputs(
      "usage: feedloop print FILE [--socket PATH] [--api PATH] [--window N] [--resume-from LINE]\n"
      "  Streams FILE to a running feedloopd (Marlin host protocol with line numbers and\n"
      "  checksums, N lines in flight, default 4) and prints a summary.\n"
      "  Lines that carry their own N and *checksum are verified and renumbered.\n"
      "  --resume-from LINE: starts at the file's physical line LINE; of the lines before it the\n"
      "  settings (temperatures, modes, limits, homing) are sent and the moves only followed, so\n"
      "  the head is placed where they left it first.\n"
      "  Exit status: 0 all lines accepted, 3 some lines answered with an error, 1 no connection.\n"
      "  Default sockets: ${RUNTIME_DIR}/feedloop.sock and ${RUNTIME_DIR}/api.sock.\n",
      stderr);
}

}  // namespace

int print_command(const std::vector<std::string>& args) {
  std::string file, socket_path, api_path;
  size_t window = 4;
  int64_t resume_from = 0;
  auto number = [](const std::string& s, int64_t* out) {
    char* end = nullptr;
    errno = 0;
    const long long v = std::strtoll(s.c_str(), &end, 10);
    if (errno != 0 || end == s.c_str() || *end != 0 || v < 1) return false;
    *out = v;
    return true;
  };
  for (size_t i = 0; i < args.size(); ++i) {
    if (args[i] == "--socket" && i + 1 < args.size()) socket_path = args[++i];
    else if (args[i] == "--api" && i + 1 < args.size()) api_path = args[++i];
    else if ((args[i] == "--window" || args[i] == "--resume-from") && i + 1 < args.size()) {
      int64_t v = 0;
      if (!number(args[i + 1], &v)) {
        std::fprintf(stderr, "feedloop print: %s needs a positive whole number, not '%s'\n", args[i].c_str(),
                     args[i + 1].c_str());
        return 2;
      }
      if (args[i] == "--window") window = static_cast<size_t>(std::min<int64_t>(v, 64));
      else resume_from = v;
      ++i;
    }
    else if (args[i] == "--help") { usage(); return 0; }
    else if (file.empty() && args[i].rfind("--", 0) != 0) file = args[i];
    else { std::fprintf(stderr, "feedloop print: unexpected argument '%s'\n", args[i].c_str()); usage(); return 2; }
  }
  if (file.empty()) { usage(); return 2; }
  const config::PathVars vars = config::path_vars_from_environment();
  if (socket_path.empty()) socket_path = *config::expand_path("${RUNTIME_DIR}/feedloop.sock", vars);
  if (api_path.empty()) api_path = *config::expand_path("${RUNTIME_DIR}/api.sock", vars);

  // A directory opens but reads as nothing; a pipe (`feedloop print <(zcat f.gcode.gz)`) is read
  // once, so its lines are not counted beforehand (progress shows lines sent alone).
  std::error_code type_error;
  const auto type = std::filesystem::status(file, type_error).type();
  if (type == std::filesystem::file_type::directory) {
    std::fprintf(stderr, "feedloop print: %s: is a directory, not a G-code file\n", file.c_str());
    return 1;
  }
  const bool counted = type == std::filesystem::file_type::regular;
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    std::fprintf(stderr, "feedloop print: cannot open %s: %s\n", file.c_str(),
                 std::strerror(errno));
    return 1;
  }
  double total_lines = 0;  // for progress: physical lines of the file (0: not known)
  if (counted) {
    char head[8] = {};
    in.read(head, sizeof head);
    if (auto kind =
            gcode::non_gcode_file_kind(std::string_view(head, static_cast<size_t>(in.gcount())))) {
      std::fprintf(stderr, "feedloop print: %s: %s\n", file.c_str(), kind->c_str());
      return 1;
    }
    in.clear();
    in.seekg(0);
    char buf[65536];
    while (in.read(buf, sizeof buf) || in.gcount() > 0) {
      total_lines += static_cast<double>(std::count(buf, buf + in.gcount(), '\n'));
      if (in.gcount() < static_cast<std::streamsize>(sizeof buf)) break;
    }
    in.clear();
    in.seekg(0);
  }
  if (counted && resume_from > static_cast<int64_t>(total_lines) + 1) {
    std::fprintf(stderr, "feedloop print: --resume-from %lld is past the end of %s (%.0f lines)\n",
                 static_cast<long long>(resume_from), file.c_str(), total_lines);
    return 2;
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
  int64_t next_n = 1, acked = 0, rejected = 0, resends = 0, lines_sent = 0, renumbered = 0;
  gcode::LineSplitter splitter;
  char chunk[65536];
  int acked_file_line = 0;
  bool eof = false;
  std::string read_error;  // the file could not be read to its end: nothing after is sent
  ResumeTracker resume;
  bool resume_preamble_sent = resume_from <= 1;
  std::string line_error;  // the Error: text of the line whose ok comes next
  Progress progress("printing " + file.substr(file.find_last_of('/') + 1));
  const auto t0 = std::chrono::steady_clock::now();

  conn.send("M110 N0\n");
  for (;;) {  // skip what a previous client may have left (e.g. a keepalive) until the ok
    auto r = conn.read_line(5000);
    if (!r) {
      std::fprintf(stderr, "feedloop print: no answer from feedloopd on %s\n", socket_path.c_str());
      return 1;
    }
    if (classify_reply(*r).kind == ReplyKind::Kind::kOk) break;
  }
  auto queue = [&](int file_line, std::string_view cmd) {
    to_send.push_back({next_n, file_line, numbered_line(next_n, cmd)});
    ++next_n;
  };
  auto reject = [&](int file_line, const std::string& message) {
    ++rejected;
    std::fprintf(stderr, "\n%s:%d: %s\n", file.c_str(), file_line, message.c_str());
  };
  auto refill = [&] {
    while (to_send.size() < 256 && !eof) {
      in.read(chunk, sizeof chunk);
      const std::streamsize got = in.gcount();
      if (in.bad()) {
        read_error = std::strerror(errno);
        eof = true;
        break;
      }
      auto on_line = [&](const gcode::SplitLine& l) {
        const int file_line = static_cast<int>(l.number);
        if (l.too_long) {
          reject(file_line, "line too long (" + std::to_string(l.length_bytes) + " bytes); not sent");
          return;
        }
        PreparedLine p = prepare_line(l.text);
        if (p.kind == PreparedLine::Kind::kBadChecksum) {
          reject(file_line, p.problem);
          return;
        }
        if (p.kind != PreparedLine::Kind::kSend) return;
        if (l.text.find('*') != std::string_view::npos) ++renumbered;
        if (l.number < resume_from) {
          if (resume.skip(p.command)) queue(file_line, p.command);
          return;
        }
        if (!resume_preamble_sent) {
          resume_preamble_sent = true;
          const std::string pre = resume.preamble();
          for (size_t b = 0, e; b < pre.size(); b = e + 1) {
            e = pre.find('\n', b);
            queue(file_line, std::string_view(pre).substr(b, e - b));
          }
        }
        queue(file_line, p.command);
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
    const ReplyKind kind = classify_reply(*reply);
    switch (kind.kind) {
      case ReplyKind::Kind::kOk:
        // The daemon answers every line in order: this ok is the oldest line's.
        if (!in_flight.empty()) {
          const Sent& s = in_flight.front();
          if (!line_error.empty()) {
            ++rejected;
            std::fprintf(stderr, "\n%s\n", locate_error(line_error, file, s.file_line).c_str());
            line_error.clear();
          }
          acked_file_line = s.file_line;
          in_flight.pop_front();
        }
        ++acked;
        break;
      case ReplyKind::Kind::kResend:
        ++resends;
        // Everything from n on goes again, in order; the ok that follows acknowledges nothing.
        while (!in_flight.empty() && in_flight.back().n >= kind.resend_n) {
          to_send.push_front(std::move(in_flight.back()));
          in_flight.pop_back();
        }
        for (;;) {  // the ok of the refused line
          auto r = conn.read_line(5000);
          if (!r || classify_reply(*r).kind == ReplyKind::Kind::kOk) break;
        }
        break;
      case ReplyKind::Kind::kError:
        if (line_error.empty()) line_error = *reply;  // one line, one rejection
        break;
      case ReplyKind::Kind::kResendError:
      case ReplyKind::Kind::kOther:
        break;  // echo:busy, echo:Unknown command, temperatures...
    }
    progress.update(total_lines > 0 ? std::min(1.0, acked_file_line / total_lines) : 0.0,
                    std::to_string(acked) + " lines acknowledged");
  }
  if (!read_error.empty()) {
    progress.finish();
    std::fprintf(stderr,
                 "\nfeedloop print: %s: read error after line %d (%s): the print stops there; "
                 "the %lld lines sent are executed\n",
                 file.c_str(), acked_file_line, read_error.c_str(),
                 static_cast<long long>(lines_sent));
    return 1;
  }
  // The last lines are acknowledged when planned; M400 returns when the machine has finished.
  conn.send(numbered_line(next_n, "M400") + "\n");
  for (;;) {
    auto reply = conn.read_line(600000);
    if (!reply) break;
    const ReplyKind k = classify_reply(*reply);
    if (k.kind == ReplyKind::Kind::kOk) break;
    if (k.kind == ReplyKind::Kind::kError) std::fprintf(stderr, "\n%s\n", reply->c_str());
  }
  progress.update(1.0, std::to_string(acked) + " lines acknowledged, machine finished");
  progress.finish();
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  std::printf("\nprint summary: %s\n", file.c_str());
  std::printf("  lines sent        %lld (%lld acknowledged, %lld rejected, %lld resends)\n",
              static_cast<long long>(lines_sent), static_cast<long long>(acked),
              static_cast<long long>(rejected), static_cast<long long>(resends));
  if (renumbered > 0)
    std::printf("  renumbered        %lld lines carried their own N/* (checked, sent under new numbers)\n",
                static_cast<long long>(renumbered));
  if (resume_from > 1) std::printf("  resumed from      line %lld\n", static_cast<long long>(resume_from));
  std::printf("  wall time         %.2f s (%.0f lines/s)\n", wall_s, lines_sent / std::max(wall_s, 1e-9));
  Connection api;
  // The last ok comes when the last line is queued: the summary waits for the machine to finish
  // its motion (and the loop to settle) so its figures cover the whole print.
  nlohmann::json status;
  if (api.open(api_path)) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(600);
    while (api.send(R"({"jsonrpc":"2.0","id":1,"method":"status"})" "\n")) {
      auto line = api.read_line(5000);
      if (!line) break;
      const auto st = nlohmann::json::parse(*line, nullptr, false);
      if (!st.is_object() || !st.contains("result")) break;
      status = st["result"];
      if (status.value("state", "") != "busy" || std::chrono::steady_clock::now() > deadline) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  }
  if (status.is_object()) {
    {
      {
        const auto& r = status;
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
        if (r.contains("motion") && r["motion"].contains("tracking_error_mm")) {
          const auto& m = r["motion"];
          std::printf("  tracking error    e_t from the encoders: mean %.4f mm, max %.4f mm (%llu samples)\n",
                      m["tracking_error_mm"]["mean"].get<double>(), m["tracking_error_mm"]["max"].get<double>(),
                      m["tracking_error_mm"]["samples"].get<unsigned long long>());
          std::printf("  lost steps        %llu events\n", m["lost_step_events"].get<unsigned long long>());
        }
        if (r.contains("motion") && r["motion"].contains("device_loops")) {
          // The PI on each axis's MCU, as its reports (100 Hz) told it.
          for (const auto& [name, l] : r["motion"]["device_loops"].items())
            std::printf("  device loop %-5s |e| mean %.4f mm, max %.4f mm; tick %.2f us mean, %.1f us max; %llu slips\n",
                        name.c_str(), l["abs_e_mm"]["mean"].get<double>(), l["abs_e_mm"]["max"].get<double>(),
                        l["tick_cost_us"]["mean"].get<double>(), l["tick_cost_us"]["max"].get<double>(),
                        l["slips"].get<unsigned long long>());
        }
        if (!r.value("last_error", "").empty())
          std::printf("  fault             %s\n", r["last_error"].get<std::string>().c_str());
        // The rest of the status (every motion figure, links, heaters) is the JSON API's `status`.
      }
    }
  }
  return rejected == 0 ? 0 : 3;
}

}  // namespace feedloop::cli
