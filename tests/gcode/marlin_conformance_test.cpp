// Host-visible behaviour that follows Marlin, each case naming the Marlin source it follows.
#include <gtest/gtest.h>

#include "gcode/host_protocol.hpp"
#include "gcode/parser.hpp"

namespace feedloop::gcode {
namespace {

std::string with_checksum(const std::string& s) { return s + "*" + std::to_string(HostProtocol::checksum(s)); }

// Marlin 1.0.x Marlin/Marlin_main.cpp, get_command(): "if we don't receive 'N' but still see '*'"
// -> "Error:No Line Number with checksum, Last Line: <n>", and the line is dropped. (Here the
// line also gets its ok, as every refused line does, so hosts counting oks go on.)
TEST(MarlinConformance, AChecksumWithoutALineNumberIsRejected) {
  HostProtocol p("host");
  Reply r;
  Command c;
  ASSERT_EQ(p.on_line(with_checksum("N1 G1 X1"), r, c), HostProtocol::Action::kExecute);
  r.clear();
  EXPECT_EQ(p.on_line(with_checksum("G1 X5"), r, c), HostProtocol::Action::kNone);
  EXPECT_EQ(r.text, "Error:No Line Number with checksum, Last Line: 1\nok\n");
  EXPECT_TRUE(c.empty());  // nothing executes
  // A '*' inside message text is not a checksum.
  r.clear();
  EXPECT_EQ(p.on_line("M117 5*5 grid", r, c), HostProtocol::Action::kExecute);
  EXPECT_EQ(c.text, "5*5 grid");
  // The line numbering goes on from the last accepted line.
  r.clear();
  EXPECT_EQ(p.on_line(with_checksum("N2 G1 X2"), r, c), HostProtocol::Action::kExecute);
}

// Marlin/src/gcode/parser.cpp, GCodeParser::parse(): "Skip spaces between parameters & values",
// so "G1 X 30" is X30 and a letter with no number after the blanks is a flag.
TEST(MarlinConformance, BlanksBetweenAParameterLetterAndItsValueAreSkipped) {
  auto c = parse_line("G1 X 30 Y  -4.5 F 1200", {"t", 1, 0});
  ASSERT_TRUE(c) << c.error().to_string();
  EXPECT_DOUBLE_EQ(c->get('X'), 30.0);
  EXPECT_DOUBLE_EQ(c->get('Y'), -4.5);
  EXPECT_DOUBLE_EQ(c->get('F'), 1200.0);
  auto home = parse_line("G28 X Y", {"t", 1, 0});
  ASSERT_TRUE(home) << home.error().to_string();
  EXPECT_TRUE(home->has('X'));
  EXPECT_TRUE(home->has('Y'));
  EXPECT_FALSE(home->has_value('X'));
  auto temp = parse_line("M104 S 215", {"t", 1, 0});
  ASSERT_TRUE(temp);
  EXPECT_DOUBLE_EQ(temp->get('S'), 215.0);
}

// Klipper's SET_VELOCITY_LIMIT is no G-code (Marlin/src/gcode/gcode.cpp answers it as an unknown
// command); the error names the dialect and the Marlin codes that set the same limits, at column 1.
TEST(MarlinConformance, KlipperExtendedCommandsGetAClearError) {
  auto c = parse_line("SET_VELOCITY_LIMIT VELOCITY=300 ACCEL=3000", {"t", 7, 0});
  ASSERT_FALSE(c);
  const std::string e = c.error().to_string();
  EXPECT_NE(e.find("t:7:1:"), std::string::npos) << e;
  EXPECT_NE(e.find("'SET_VELOCITY_LIMIT' is a Klipper extended command"), std::string::npos) << e;
  EXPECT_NE(e.find("M203"), std::string::npos) << e;
  EXPECT_EQ(e.find("before any command"), std::string::npos) << e;
  // A stray parameter keeps its own message.
  auto x = parse_line("X10", {"t", 1, 0});
  ASSERT_FALSE(x);
  EXPECT_NE(x.error().to_string().find("before any command"), std::string::npos);
}

// Marlin/src/gcode/feature/fwretract/G10_G11.cpp reads only S (as a bool) and ignores the other
// words, so "G10 S210 P0" is accepted. Hosts send it as RepRapFirmware's temperature form
// (P tool, S active, R standby temperature); feedloop takes that meaning (engine/machine.cpp).
TEST(MarlinConformance, G10TemperatureFormIsAccepted) {
  auto c = parse_line("G10 S210 P0", {"t", 1, 0});
  ASSERT_TRUE(c) << c.error().to_string();
  EXPECT_DOUBLE_EQ(c->get('S'), 210.0);
  EXPECT_DOUBLE_EQ(c->get('P'), 0.0);
  EXPECT_TRUE(parse_line("G10 P0 S215 R170", {"t", 1, 0}));
  EXPECT_TRUE(parse_line("G10", {"t", 1, 0}));
  EXPECT_TRUE(parse_line("G10 S1", {"t", 1, 0}));
}

}  // namespace
}  // namespace feedloop::gcode
