// What `feedloop print` sends for each line of a G-code file, and how it reads the daemon's
// replies. No I/O here, so the rules are tested without a daemon.
//
// Lines that already carry a line number and a checksum ("N12 G1 X5*71", as written by
// tools/add_checksums.py or a host's log) are RENUMBERED: the client owns the connection's line
// numbers (it starts them with its own M110 and re-sends from its own buffer), so the file's N
// word and checksum are verified, then dropped, and the command goes out under the next number.
// A file line whose checksum does not match is not sent: it is reported with its file line and
// counted as rejected (the bytes were damaged; printing a guess is worse than a gap the user
// sees). M110 lines of the file are skipped for the same reason (they would reset the numbering).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace feedloop::cli {

// One file line, prepared.
struct PreparedLine {
  enum class Kind { kSkip, kSend, kBadChecksum };
  Kind kind = Kind::kSkip;
  std::string command;  // kSend: the command without comment, N word or checksum
  std::string problem;  // kBadChecksum: what is wrong
};

PreparedLine prepare_line(std::string_view raw);

// "N<n> <cmd>*<xor>" as the Marlin host protocol wants it.
std::string numbered_line(int64_t n, std::string_view cmd);

// A reply line from the daemon, classified.
struct ReplyKind {
  enum class Kind { kOk, kError, kResendError, kResend, kOther };
  Kind kind = Kind::kOther;
  int64_t resend_n = 0;  // kResend
};
ReplyKind classify_reply(std::string_view reply);

// An "Error:" reply's message with the daemon's location ("socket-3:1207:9: ") replaced by the
// file's: "cube.gcode:1180:9: message". Messages without a location get "file:line: ".
std::string locate_error(std::string_view error_text, const std::string& file, int file_line);

// Tracks the modal state of the lines skipped by --resume-from and writes the preamble that
// restores it: settings lines (temperatures, units, modes, limits, fan) are sent as they are;
// moves are not sent but followed, so the printer is homed, heated and positioned at the place
// the skipped lines left it before the first resumed line.
class ResumeTracker {
 public:
  // A skipped command (already prepared: no comment, no N/*). Returns true when it must still be
  // sent (a setting), false when it is only followed (a move, a progress line).
  bool skip(std::string_view command);
  // The lines to send after the settings and before the first resumed line.
  std::string preamble() const;

 private:
  bool absolute_xyz_ = true;
  bool absolute_e_ = true;
  double pos_[4] = {0, 0, 0, 0};  // X Y Z E as the file's coordinates
  bool known_[4] = {false, false, false, false};
  double feed_mm_min_ = 0;
};

}  // namespace feedloop::cli
