// The Marlin host protocol spoken on every serial-like channel (pty, Unix socket, serial): one
// `ok` per accepted line, line numbers N and checksums *, `Resend:` requests, M110, `Error:`
// lines, and M112 as an emergency that bypasses every queue. Replies match Marlin 2.x byte for
// byte where Marlin defines them (Marlin/src/gcode/queue.cpp, language.h), so Printrun/pronsole,
// OctoPrint and other hosts work unchanged:
//
//   N41 G1 X1*<bad>   ->  Error:checksum mismatch, Last Line: 40
//                          Resend: 41
//                          ok
//   N43 ... (expected 42) -> Error:Line Number is not Last Line Number+1, Last Line: 41 / Resend: 42 / ok
//   N42 G1 X1  (no *)  ->  Error:No Checksum with line number, Last Line: 41 / Resend: 42 / ok
//   G1 X1*75   (no N)  ->  Error:No Line Number with checksum, Last Line: 41 / ok   (nothing executed)
//   M110 N100          ->  ok, and the next expected line is N101
//   G1 X1 Q2 (invalid) ->  Error:<source>:<line>:<column>: <message> / ok   (nothing executed)
//   M998 (unknown)     ->  echo:Unknown command: "M998" / ok   (still returned to the caller)
//
// As in Marlin the sequence check comes before the checksum check, the checksum is the XOR of
// every byte from the first non-blank one up to the last '*', and blank or comment-only lines
// get no reply at all. M112 is recognised before any check (even with a bad checksum), like
// Marlin's emergency parser: on_line returns kEmergencyStop and sends nothing; the caller stops
// the machine at once and reports. A line that fails anywhere executes nothing.
//
// Flow control: with Options::defer_ok the `ok` of an executable command is not written; the
// caller sends it (acknowledge()) when its queue has accepted the command, which throttles the
// host to the queue's pace. Errors, M110 and empty commands are acknowledged at once.
// Owner: the I/O thread of one channel (one HostProtocol per connected client).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "gcode/command.hpp"
#include "gcode/line_splitter.hpp"

namespace feedloop::gcode {

// Text to send back to the host: complete lines, each ending in '\n'. Reuse one Reply (clear())
// to avoid allocation per line.
struct Reply {
  std::string text;
  void clear() { text.clear(); }
  void line(std::string_view s) {
    text.append(s);
    text.push_back('\n');
  }
};

class HostProtocol {
 public:
  enum class Action {
    kNone,           // nothing to execute (blank line, error, resend, M110 handled here)
    kExecute,        // `command` holds a parsed, validated command to execute
    kEmergencyStop,  // M112: stop everything now, bypassing queues
  };

  struct Options {
    bool defer_ok = false;      // the caller calls acknowledge() once the command is queued
    bool warn_unknown = true;   // echo:Unknown command: "..." for commands the parser flags
    // Commands the parser does not know that the caller carries out all the same (the daemon's
    // M0 / M1 / M600 / M876): no "Unknown command" for them.
    bool (*caller_handles)(const Command&) = nullptr;
  };

  struct Stats {
    int64_t lines_received = 0;    // physical lines handed to on_line / on_too_long
    int64_t commands_executed = 0; // kExecute results
    int64_t resends_requested = 0;
    int64_t parse_errors = 0;
  };

  explicit HostProtocol(std::string source_name = "host");
  HostProtocol(std::string source_name, Options options);

  // One line as received (without its line end). Writes the reply to `out` (appends) and, for
  // kExecute, the command to `command`.
  Action on_line(std::string_view raw, Reply& out, Command& command);

  // A line the LineSplitter reported as too long: an Error line and an ok; nothing executes.
  Action on_too_long(const SplitLine& line, Reply& out);

  // The deferred `ok` for a command that on_line returned as kExecute (Options::defer_ok).
  static void acknowledge(Reply& out) { out.line(kOk); }

  // True when `raw` is an M112 (optionally after an N word), whatever its checksum. The I/O
  // thread may call it directly on received bytes to bypass every queue.
  static bool is_emergency_stop(std::string_view raw);
  // True when `raw` is an M108 (Marlin's break and continue, which its emergency parser also takes
  // ahead of the queue), optionally after an N word, whatever its checksum.
  static bool is_break_and_continue(std::string_view raw);
  // True when `raw` is an M876 (the host's answer to a prompt, Marlin's HOST_PROMPT_SUPPORT, which
  // its emergency parser takes too), optionally after an N word.
  static bool is_prompt_response(std::string_view raw);

  // XOR of all bytes of `s` (the Marlin checksum of the text before '*').
  static uint8_t checksum(std::string_view s);

  int64_t last_line_number() const { return last_n_; }
  const Stats& stats() const { return stats_; }
  const Options& options() const { return options_; }

  static constexpr std::string_view kOk = "ok";
  static constexpr std::string_view kErrLineNo =
      "Line Number is not Last Line Number+1, Last Line: ";
  static constexpr std::string_view kErrChecksumMismatch = "checksum mismatch, Last Line: ";
  static constexpr std::string_view kErrNoChecksum = "No Checksum with line number, Last Line: ";
  static constexpr std::string_view kErrNoLineNumber = "No Line Number with checksum, Last Line: ";
  static constexpr std::string_view kResend = "Resend: ";
  static constexpr std::string_view kHalted = "Error:Printer halted. kill() called!";

 private:
  void line_error(std::string_view message, Reply& out);

  std::string source_;
  SourceLocation where_;  // source_ and the current physical line, reused for every parse
  Options options_;
  int64_t last_n_ = 0;  // Marlin's last_N: the last accepted line number
  int64_t physical_line_ = 0;
  Stats stats_;
};

}  // namespace feedloop::gcode
