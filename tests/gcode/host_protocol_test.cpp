// The Marlin host protocol: exact replies for checksums, resends (bad checksum, skipped number,
// missing checksum), M110, duplicates after a resend, ok counting, deferred ok, M112.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "gcode/host_protocol.hpp"

namespace feedloop::gcode {
namespace {

using Action = HostProtocol::Action;

std::string numbered(int64_t n, const std::string& cmd) {
  const std::string body = "N" + std::to_string(n) + " " + cmd;
  return body + "*" + std::to_string(HostProtocol::checksum(body));
}

struct Exchange {
  Action action;
  std::string reply;
  Command command;
};

Exchange send(HostProtocol& p, const std::string& line) {
  Exchange e;
  Reply r;
  e.action = p.on_line(line, r, e.command);
  e.reply = r.text;
  return e;
}

TEST(HostProtocol, ChecksumIsXorOfBytesBeforeStar) {
  EXPECT_EQ(HostProtocol::checksum("N0 M110 N0"), 125);  // the corpus file's first line
  EXPECT_EQ(numbered(1, "M73 P0 R13"), "N1 M73 P0 R13*38");
}

TEST(HostProtocol, UnnumberedLinesGetOneOkEach) {
  HostProtocol p;
  Exchange e = send(p, "G1 X10 F3000");
  EXPECT_EQ(e.action, Action::kExecute);
  EXPECT_EQ(e.reply, "ok\n");
  EXPECT_DOUBLE_EQ(e.command.get('X'), 10.0);
  e = send(p, "  ; just a comment");
  EXPECT_EQ(e.action, Action::kNone);
  EXPECT_EQ(e.reply, "");  // Marlin sends nothing for blank / comment-only lines
  e = send(p, "");
  EXPECT_EQ(e.reply, "");
  e = send(p, "(inline only)");
  EXPECT_EQ(e.reply, "ok\n");
  EXPECT_EQ(p.stats().commands_executed, 1);
}

TEST(HostProtocol, NumberedSequenceAndExactErrorReplies) {
  HostProtocol p;
  Exchange e = send(p, "N0 M110 N0*125");
  EXPECT_EQ(e.action, Action::kNone);
  EXPECT_EQ(e.reply, "ok\n");
  EXPECT_EQ(p.last_line_number(), 0);

  e = send(p, numbered(1, "G1 X1"));
  EXPECT_EQ(e.action, Action::kExecute);
  EXPECT_EQ(e.reply, "ok\n");
  EXPECT_EQ(e.command.line_number, 1);

  // Bad checksum.
  std::string bad = numbered(2, "G1 X2");
  bad.back() = bad.back() == '0' ? '1' : '0';
  e = send(p, bad);
  EXPECT_EQ(e.action, Action::kNone);
  EXPECT_TRUE(e.command.empty());
  EXPECT_EQ(e.reply, "Error:checksum mismatch, Last Line: 1\nResend: 2\nok\n");

  // Skipped number (N3 while 2 is expected).
  e = send(p, numbered(3, "G1 X3"));
  EXPECT_EQ(e.action, Action::kNone);
  EXPECT_EQ(e.reply, "Error:Line Number is not Last Line Number+1, Last Line: 1\nResend: 2\nok\n");

  // Missing checksum on a numbered line.
  e = send(p, "N2 G1 X2");
  EXPECT_EQ(e.action, Action::kNone);
  EXPECT_EQ(e.reply, "Error:No Checksum with line number, Last Line: 1\nResend: 2\nok\n");

  e = send(p, numbered(2, "G1 X2"));
  EXPECT_EQ(e.action, Action::kExecute);
  EXPECT_EQ(e.reply, "ok\n");
  EXPECT_EQ(p.last_line_number(), 2);
  EXPECT_EQ(p.stats().resends_requested, 3);
}

TEST(HostProtocol, DuplicateLinesAfterAResendExecuteOnce) {
  // A host pipelines N11 and N12; N11 is corrupted on the wire. Marlin asks for 11 again and
  // rejects N12 until 11 arrives; the host then sends 11, 12 and (stale) 12 again.
  HostProtocol p;
  std::vector<double> executed;
  auto feed = [&](const std::string& line) {
    Exchange e = send(p, line);
    if (e.action == Action::kExecute) executed.push_back(e.command.get('X'));
    return e.reply;
  };
  feed("M110 N10");
  std::string corrupt = numbered(11, "G1 X11");
  corrupt[4] = 'Y';  // payload changed, checksum not
  EXPECT_EQ(feed(corrupt), "Error:checksum mismatch, Last Line: 10\nResend: 11\nok\n");
  EXPECT_EQ(feed(numbered(12, "G1 X12")),
            "Error:Line Number is not Last Line Number+1, Last Line: 10\nResend: 11\nok\n");
  EXPECT_EQ(feed(numbered(11, "G1 X11")), "ok\n");
  EXPECT_EQ(feed(numbered(12, "G1 X12")), "ok\n");
  EXPECT_EQ(feed(numbered(12, "G1 X12")),
            "Error:Line Number is not Last Line Number+1, Last Line: 12\nResend: 13\nok\n");
  EXPECT_EQ(feed(numbered(13, "G1 X13")), "ok\n");
  EXPECT_EQ(executed, (std::vector<double>{11, 12, 13}));
}

TEST(HostProtocol, M110ResetsTheExpectedNumber) {
  HostProtocol p;
  EXPECT_EQ(send(p, "M110 N100").reply, "ok\n");
  EXPECT_EQ(p.last_line_number(), 100);
  EXPECT_EQ(send(p, numbered(101, "G28")).action, Action::kExecute);
  // A numbered M110 is exempt from the sequence check and sets the number it carries.
  EXPECT_EQ(send(p, numbered(5, "M110 N40")).reply, "ok\n");
  EXPECT_EQ(p.last_line_number(), 40);
  // Without an N parameter, the line's own number is taken.
  EXPECT_EQ(send(p, numbered(7, "M110")).reply, "ok\n");
  EXPECT_EQ(p.last_line_number(), 7);
  EXPECT_EQ(send(p, numbered(8, "G90")).action, Action::kExecute);
  // Printrun's printcore starts a print with "N-1 M110": the next line is N0.
  EXPECT_EQ(send(p, numbered(-1, "M110")).reply, "ok\n");
  EXPECT_EQ(p.last_line_number(), -1);
  EXPECT_EQ(send(p, numbered(0, "G91")).action, Action::kExecute);
}

TEST(HostProtocol, ParseErrorsReplyErrorAndOkAndExecuteNothing) {
  HostProtocol p("pty");
  send(p, "M110 N2");
  Exchange e = send(p, numbered(3, "M104 S-20"));
  EXPECT_EQ(e.action, Action::kNone);
  EXPECT_TRUE(e.command.empty());
  EXPECT_EQ(e.reply,
            "Error:pty:2:9: M104 (set hotend temperature): S must be between 0 and 1000 (got -20)\n"
            "ok\n");
  EXPECT_EQ(p.last_line_number(), 3);  // the line arrived intact; resending would not help
  EXPECT_EQ(send(p, numbered(4, "M104 S200")).action, Action::kExecute);
  EXPECT_EQ(p.stats().parse_errors, 1);
}

TEST(HostProtocol, UnknownCommandsWarnAndStillReachTheCaller) {
  HostProtocol p;
  Exchange e = send(p, numbered(1, "M572 S0.05"));
  EXPECT_EQ(e.action, Action::kExecute);
  EXPECT_TRUE(e.command.unknown);
  EXPECT_EQ(e.reply, "echo:Unknown command: \"M572 S0.05\"\nok\n");
  HostProtocol quiet("q", {.defer_ok = false, .warn_unknown = false});
  EXPECT_EQ(send(quiet, "M572 S0").reply, "ok\n");
}

TEST(HostProtocol, DeferredOkIsSentByTheCaller) {
  HostProtocol p("sock", {.defer_ok = true, .warn_unknown = true});
  Exchange e = send(p, "G1 X1");
  EXPECT_EQ(e.action, Action::kExecute);
  EXPECT_EQ(e.reply, "");
  Reply r;
  HostProtocol::acknowledge(r);
  EXPECT_EQ(r.text, "ok\n");
  // Lines with nothing to queue are acknowledged at once.
  EXPECT_EQ(send(p, "M110 N0").reply, "ok\n");
  EXPECT_EQ(send(p, "G1 Q1").reply.substr(0, 6), "Error:");
}

TEST(HostProtocol, EmergencyStopBypassesEveryCheck) {
  HostProtocol p;
  send(p, "M110 N10");
  EXPECT_EQ(send(p, "M112").action, Action::kEmergencyStop);
  EXPECT_EQ(send(p, "N99 M112*0").action, Action::kEmergencyStop);  // wrong number and checksum
  EXPECT_EQ(send(p, "  m112 ; stop").action, Action::kEmergencyStop);
  EXPECT_EQ(send(p, "(panic) M112").action, Action::kEmergencyStop);
  EXPECT_EQ(send(p, "M112").reply, "");
  EXPECT_EQ(p.last_line_number(), 10);  // untouched
  EXPECT_TRUE(HostProtocol::is_emergency_stop("N5 M112*17"));
  EXPECT_FALSE(HostProtocol::is_emergency_stop("M1120"));
  EXPECT_FALSE(HostProtocol::is_emergency_stop("M11"));
  EXPECT_FALSE(HostProtocol::is_emergency_stop("G1 X1 ; M112"));
}

// M108 (break and continue) is recognised on the raw line as M112 is, so the daemon can end a
// heater wait ahead of the queue; the line itself then goes through the protocol as any other.
TEST(HostProtocol, BreakAndContinueIsRecognisedOnTheRawLine) {
  EXPECT_TRUE(HostProtocol::is_break_and_continue("M108"));
  EXPECT_TRUE(HostProtocol::is_break_and_continue("N7 M108*12"));
  EXPECT_TRUE(HostProtocol::is_break_and_continue("  m108 ; skip the heat-up"));
  EXPECT_FALSE(HostProtocol::is_break_and_continue("M1080"));
  EXPECT_FALSE(HostProtocol::is_break_and_continue("M10"));
  EXPECT_FALSE(HostProtocol::is_break_and_continue("M112"));
  EXPECT_FALSE(HostProtocol::is_emergency_stop("M108"));
  EXPECT_FALSE(HostProtocol::is_break_and_continue("G1 X1 ; M108"));
  HostProtocol p;
  EXPECT_EQ(send(p, "N1 M108*43").action, Action::kExecute);  // checked and answered in order
}

TEST(HostProtocol, OneOkPerNonBlankLine) {
  HostProtocol p;
  const std::vector<std::string> lines = {
      "M110 N0", numbered(1, "G28"), "", "; c", numbered(2, "G1 X1 Q2"), numbered(4, "G1 X4"),
      numbered(3, "G1 X3"), "M998", "G1 X5", "N4", "(c)", numbered(4, "G1 X4")};
  int oks = 0, non_blank = 0;
  for (const auto& l : lines) {
    Reply r;
    Command c;
    p.on_line(l, r, c);
    for (size_t pos = r.text.find("ok\n"); pos != std::string::npos; pos = r.text.find("ok\n", pos + 1))
      if (pos == 0 || r.text[pos - 1] == '\n') ++oks;
    if (l != "" && l != "; c") ++non_blank;
  }
  EXPECT_EQ(oks, non_blank);
}

TEST(HostProtocol, TooLongLineIsAnErrorWithOk) {
  HostProtocol p("pty");
  SplitLine l;
  l.too_long = true;
  l.length_bytes = 300000;
  Reply r;
  EXPECT_EQ(p.on_too_long(l, r), Action::kNone);
  EXPECT_EQ(r.text, "Error:pty:1: line too long (300000 bytes); ignored\nok\n");
}

TEST(HostProtocol, StreamWithAMegabyteLineKeepsWorking) {
  // Bytes as a pty delivers them: a numbered stream with a 1 MB garbage line in the middle.
  HostProtocol p("pty");
  LineSplitter splitter;
  std::string stream = "M110 N0\n" + numbered(1, "G28") + "\n" + std::string(1 << 20, 'G') + "\n" +
                       numbered(2, "G1 X5") + "\n";
  std::string replies;
  std::vector<double> executed;
  Reply r;
  Command c;
  auto on_line = [&](const SplitLine& l) {
    r.clear();
    const Action a = l.too_long ? p.on_too_long(l, r) : p.on_line(l.text, r, c);
    if (a == Action::kExecute) executed.push_back(c.get('X', -1));
    replies += r.text;
  };
  for (size_t i = 0; i < stream.size(); i += 4096)
    splitter.feed(std::string_view(stream).substr(i, 4096), on_line);
  splitter.finish(on_line);
  EXPECT_EQ(replies, "ok\nok\nError:pty:3: line too long (1048576 bytes); ignored\nok\nok\n");
  EXPECT_EQ(executed, (std::vector<double>{-1, 5}));
  EXPECT_EQ(p.last_line_number(), 2);
}

}  // namespace
}  // namespace feedloop::gcode
