// feedloop print's rules for file lines and daemon replies (cli/print_lines.hpp).
#include "cli/print_lines.hpp"

#include <gtest/gtest.h>

#include "gcode/host_protocol.hpp"

namespace feedloop::cli {
namespace {

TEST(PrepareLine, StripsCommentsAndSkipsBlankLines) {
  EXPECT_EQ(prepare_line("  G1 X5 Y6 ; move").command, "G1 X5 Y6");
  EXPECT_EQ(prepare_line("  G1 X5 Y6 ; move").kind, PreparedLine::Kind::kSend);
  EXPECT_EQ(prepare_line("; only a comment").kind, PreparedLine::Kind::kSkip);
  EXPECT_EQ(prepare_line("   \r").kind, PreparedLine::Kind::kSkip);
}

TEST(PrepareLine, VerifiesAndDropsTheFilesOwnLineNumberAndChecksum) {
  // The numbered cube's lines, as tools/add_checksums.py writes them.
  const std::string body = "N7 G1 X5 Y5 F6000";
  const std::string line = body + "*" + std::to_string(gcode::HostProtocol::checksum(body));
  const PreparedLine p = prepare_line(line);
  EXPECT_EQ(p.kind, PreparedLine::Kind::kSend);
  EXPECT_EQ(p.command, "G1 X5 Y5 F6000");
  // The client owns the numbering: the file's M110 is not sent.
  EXPECT_EQ(prepare_line("N0 M110 N0*125").kind, PreparedLine::Kind::kSkip);
  // A damaged line is not sent.
  const std::string bad = body + "*" + std::to_string((gcode::HostProtocol::checksum(body) + 1) % 256);
  const PreparedLine b = prepare_line(bad);
  EXPECT_EQ(b.kind, PreparedLine::Kind::kBadChecksum);
  EXPECT_NE(b.problem.find(std::to_string(gcode::HostProtocol::checksum(body))), std::string::npos) << b.problem;
}

TEST(ClassifyReply, OkWithOrWithoutPayload) {
  EXPECT_EQ(classify_reply("ok").kind, ReplyKind::Kind::kOk);
  EXPECT_EQ(classify_reply("ok T:21.0 /0.0 B:21.0 /0.0 @:0 B@:0").kind, ReplyKind::Kind::kOk);
  EXPECT_EQ(classify_reply("okay").kind, ReplyKind::Kind::kOther);
  EXPECT_EQ(classify_reply("echo:busy: processing").kind, ReplyKind::Kind::kOther);
  const ReplyKind r = classify_reply("Resend: 4512");
  EXPECT_EQ(r.kind, ReplyKind::Kind::kResend);
  EXPECT_EQ(r.resend_n, 4512);
  EXPECT_EQ(classify_reply("Error:checksum mismatch, Last Line: 40").kind, ReplyKind::Kind::kResendError);
  EXPECT_EQ(classify_reply("Error:socket-2:17:8: unknown parameter 'Q'").kind, ReplyKind::Kind::kError);
}

TEST(LocateError, ReplacesTheConnectionsLocationWithTheFiles) {
  EXPECT_EQ(locate_error("Error:socket-2:1207:9: unknown parameter 'Q'", "cube.gcode", 1180),
            "cube.gcode:1180:9: unknown parameter 'Q'");
  EXPECT_EQ(locate_error("Error:busy: the print is owned by socket-1", "a.gcode", 3),
            "a.gcode:3: busy: the print is owned by socket-1");
}

TEST(ResumeTracker, SendsSettingsFollowsMovesAndPlacesTheHead) {
  ResumeTracker t;
  EXPECT_TRUE(t.skip("M104 S215"));
  EXPECT_TRUE(t.skip("G28"));
  EXPECT_TRUE(t.skip("M83"));
  EXPECT_FALSE(t.skip("G1 X10 Y20 Z0.3 E1.5 F1200"));
  EXPECT_FALSE(t.skip("G1 X15 E0.5"));
  EXPECT_FALSE(t.skip("M73 P5"));
  EXPECT_FALSE(t.skip("M105"));
  EXPECT_EQ(t.preamble(), "G90\nG1 Z0.3 F600\nG1 X15 Y20 F3000\nG92 E2\nM83\nG1 F1200\n");
}

}  // namespace
}  // namespace feedloop::cli
