// The dialect: comments, case, whitespace, numbers, exponents vs the E word, N, checksum
// suffixes, free text, unknown commands, error columns and very long lines.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "gcode/parser.hpp"

namespace feedloop::gcode {
namespace {

Command ok(std::string_view line) {
  auto r = parse_line(line, SourceLocation{"t.gcode", 7, 0});
  EXPECT_TRUE(r.ok()) << line << " -> " << (r.ok() ? "" : r.error().to_string());
  return r.ok() ? r.value() : Command{};
}

Error err(std::string_view line) {
  auto r = parse_line(line, SourceLocation{"t.gcode", 7, 0});
  EXPECT_FALSE(r.ok()) << line << " parsed but should not";
  return r.ok() ? Error{} : r.error();
}

TEST(Parser, PlainMoveWithAllAxes) {
  const Command c = ok("G1 X10.5 Y-3 Z.2 E-.8 F7800");
  EXPECT_TRUE(c.is('G', 1));
  EXPECT_FALSE(c.unknown);
  EXPECT_DOUBLE_EQ(c.get('X'), 10.5);
  EXPECT_DOUBLE_EQ(c.get('Y'), -3.0);
  EXPECT_DOUBLE_EQ(c.get('Z'), 0.2);
  EXPECT_DOUBLE_EQ(c.get('E'), -0.8);
  EXPECT_DOUBLE_EQ(c.get('F'), 7800.0);
  EXPECT_EQ(c.where.source, "t.gcode");
  EXPECT_EQ(c.where.line, 7);
}

TEST(Parser, NumbersAreCorrectlyRounded) {
  // Same double as strtod for short decimals (fast path) and for long ones (from_chars path).
  for (const char* v : {"0.1", "123.456", "-0.000001", "99999.99999", "1.7976931348623157",
                        "0.30000000000000004441", "12345678901234567890.5", "+5", "5.", ".5"}) {
    const Command c = ok(std::string("G1 X") + v);
    EXPECT_EQ(c.get('X'), std::strtod(v, nullptr)) << v;
  }
}

TEST(Parser, CaseAndWhitespaceDoNotMatter) {
  for (const char* line : {"g1 x10 y20 e1.5 f3000", "G1X10Y20E1.5F3000", "  G1\tX10  Y20 E1.5 F3000  ",
                           "G1 X10 Y20 E1.5 F3000\r", "G01 X10 Y20 E1.5 F3000"}) {
    const Command c = ok(line);
    EXPECT_TRUE(c.is('G', 1)) << line;
    EXPECT_DOUBLE_EQ(c.get('X'), 10.0) << line;
    EXPECT_DOUBLE_EQ(c.get('Y'), 20.0) << line;
    EXPECT_DOUBLE_EQ(c.get('E'), 1.5) << line;
    EXPECT_DOUBLE_EQ(c.get('F'), 3000.0) << line;
  }
}

TEST(Parser, ExponentVersusEWord) {
  // The E word, however it is glued on.
  for (const char* line : {"G1 X10 E5", "G1X10E5", "G1 X10E5", "g1x10e5"}) {
    const Command c = ok(line);
    EXPECT_DOUBLE_EQ(c.get('X'), 10.0) << line;
    EXPECT_DOUBLE_EQ(c.get('E'), 5.0) << line;
  }
  for (const char* line : {"G1X10E-5", "G1 X10E-5", "g1x10e-5", "G1 X10 E-5"}) {
    const Command c = ok(line);
    EXPECT_DOUBLE_EQ(c.get('X'), 10.0) << line;
    EXPECT_DOUBLE_EQ(c.get('E'), -5.0) << line;
  }
  // An exponent: lowercase e, explicit sign, a digit, in a word that follows whitespace.
  Command c = ok("G1 X1e-05 Y2.5e+2 E3");
  EXPECT_DOUBLE_EQ(c.get('X'), 1e-5);
  EXPECT_DOUBLE_EQ(c.get('Y'), 250.0);
  EXPECT_DOUBLE_EQ(c.get('E'), 3.0);
  // No sign -> E word; uppercase E -> E word.
  c = ok("G1 X1e5");
  EXPECT_DOUBLE_EQ(c.get('X'), 1.0);
  EXPECT_DOUBLE_EQ(c.get('E'), 5.0);
  c = ok("G1 X1E+5");
  EXPECT_DOUBLE_EQ(c.get('X'), 1.0);
  EXPECT_DOUBLE_EQ(c.get('E'), 5.0);
  // An exponent that overflows a double is an error, not infinity.
  EXPECT_EQ(err("G1 X1e+999").where.column, 4);
}

TEST(Parser, Comments) {
  Command c = ok("G1 X1 ; move (not a comment start here) *12");
  EXPECT_DOUBLE_EQ(c.get('X'), 1.0);
  EXPECT_FALSE(c.has('Y'));
  c = ok("G1 (first) X1 (second;third) Y2");
  EXPECT_DOUBLE_EQ(c.get('X'), 1.0);
  EXPECT_DOUBLE_EQ(c.get('Y'), 2.0);
  EXPECT_TRUE(ok("; only a comment").empty());
  EXPECT_TRUE(ok("(only a comment)").empty());
  EXPECT_TRUE(ok("").empty());
  EXPECT_TRUE(ok("   \t ").empty());
  const Error e = err("G1 X1 (unclosed");
  EXPECT_EQ(e.where.column, 7);
  EXPECT_NE(e.message.find("unclosed"), std::string::npos);
}

TEST(Parser, LineNumberAndChecksumSuffix) {
  Command c = ok("N42 G1 X5*87");
  EXPECT_EQ(c.line_number, 42);
  EXPECT_DOUBLE_EQ(c.get('X'), 5.0);
  c = ok("N0 M110 N0*125");
  EXPECT_TRUE(c.is('M', 110));
  EXPECT_EQ(c.line_number, 0);
  EXPECT_DOUBLE_EQ(c.get('N'), 0.0);
  c = ok("N7");
  EXPECT_TRUE(c.empty());
  EXPECT_EQ(c.line_number, 7);
  EXPECT_EQ(err("G1 X5*").where.column, 6);
  EXPECT_EQ(err("G1 X5*12 Y3").where.column, 6);
  EXPECT_EQ(err("N G1").where.column, 1);
  EXPECT_EQ(err("N99999999999999999999 G1").where.column, 1);
}

TEST(Parser, FreeTextCommandsKeepTheirText) {
  Command c = ok("M117 Hello (world) *starred");
  EXPECT_TRUE(c.is('M', 117));
  EXPECT_FALSE(c.unknown);
  EXPECT_EQ(c.text, "Hello (world) *starred");
  EXPECT_FALSE(c.has_any_parameter());
  c = ok("N12 M117 Layer 3 of 20*99");
  EXPECT_EQ(c.text, "Layer 3 of 20");
  EXPECT_EQ(c.line_number, 12);
  c = ok("M117Compact ; comment");
  EXPECT_EQ(c.text, "Compact");
  c = ok("M23 /models/part X1.gco");
  EXPECT_TRUE(c.is('M', 23));
  EXPECT_EQ(c.text, "/models/part X1.gco");
  EXPECT_FALSE(c.has('X'));
  c = ok("M118 E1 busy: processing");
  EXPECT_EQ(c.text, "E1 busy: processing");
}

TEST(Parser, KlippersObjectLabelsBecomeM486WithTheFormAndTheName) {
  // As PrusaSlicer and OrcaSlicer write them for a Klipper printer (label objects: firmware).
  Command c =
      ok("EXCLUDE_OBJECT_DEFINE NAME='Shape-Box id:0 copy 0' CENTER=110,110 "
         "POLYGON=[[100,100],[120,100],[120, 120]] ; comment");
  EXPECT_TRUE(c.is('M', 486));
  EXPECT_FALSE(c.unknown);
  EXPECT_EQ(c.subcode, kObjectDefine);
  EXPECT_EQ(c.text, "SHAPE-BOX ID:0 COPY 0");  // upper-cased, as Klipper does
  c = ok("exclude_object_start name=part_1");
  EXPECT_EQ(c.subcode, kObjectStart);
  EXPECT_EQ(c.text, "PART_1");
  c = ok("EXCLUDE_OBJECT_END");
  EXPECT_EQ(c.subcode, kObjectEnd);
  EXPECT_TRUE(c.text.empty());
  c = ok("EXCLUDE_OBJECT CURRENT=1");
  EXPECT_EQ(c.subcode, kObjectExclude);
  EXPECT_TRUE(c.has('C'));
  c = ok("EXCLUDE_OBJECT_DEFINE RESET=1");
  EXPECT_TRUE(c.has('R'));
  c = ok("M486.2 X");  // typed literally: not the Klipper form
  EXPECT_TRUE(c.unknown);
  auto bad = parse_line("EXCLUDE_OBJECT_START", SourceLocation{"t", 4, 0});
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("needs NAME="), std::string::npos) << bad.error().message;
  bad = parse_line("EXCLUDE_OBJECT_START NAME=a COLOR=red", SourceLocation{"t", 4, 0});
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.error().where.column, 29);
  EXPECT_NE(bad.error().message.find("unknown parameter COLOR"), std::string::npos);
  bad = parse_line("EXCLUDE_OBJECT NAME=a CURRENT=1", SourceLocation{"t", 4, 0});
  ASSERT_FALSE(bad.ok());
  bad = parse_line("EXCLUDE_OBJECT_DEFINE NAME='open", SourceLocation{"t", 4, 0});
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("unclosed quote"), std::string::npos);
}

// Marlin's own M486 (CANCEL_OBJECTS), as PrusaSlicer writes it for a Marlin printer: the index
// is the object's name until a name line (A) gives it one.
TEST(Parser, MarlinsObjectLabelsBecomeTheSameFormsWithTheIndexAsName) {
  Command c = ok("M486 T3");
  EXPECT_FALSE(c.unknown);
  EXPECT_EQ(c.subcode, kObjectDefine);
  EXPECT_TRUE(c.has('R'));  // a new plate
  c = ok("M486 S2 ; printing object 2");
  EXPECT_FALSE(c.unknown);
  EXPECT_EQ(c.subcode, kObjectStart);
  EXPECT_EQ(c.text, "2");
  c = ok("M486 S-1");
  EXPECT_EQ(c.subcode, kObjectEnd);
  EXPECT_TRUE(c.text.empty());
  c = ok("M486 P12");
  EXPECT_EQ(c.subcode, kObjectExclude);
  EXPECT_EQ(c.text, "12");
  EXPECT_FALSE(c.has('C'));
  c = ok("M486 C");
  EXPECT_EQ(c.subcode, kObjectExclude);
  EXPECT_TRUE(c.has('C'));
  // The translated forms keep no Marlin parameter (only the Klipper forms' flags).
  c = ok("M486 P3");
  EXPECT_FALSE(c.has('P'));
  EXPECT_FALSE(c.has_any_parameter());
  // Names (PrusaSlicer's "M486 A<name>" after the S line): free text, whatever letters, stars or
  // quotes it holds, upper-cased, with '_' for what would end an EXCLUDE_OBJECT NAME= value.
  for (const auto& [line, name] : std::vector<std::pair<std::string, std::string>>{
           {"M486 AShape-Box id:0 copy 0", "SHAPE-BOX_ID:0_COPY_0"},
           {"M486 AShape-Box (Instance 1) ; a comment", "SHAPE-BOX_(INSTANCE_1)"},
           {"M486 AP2", "P2"},  // a name, not a cancel
           {"M486 AS", "S"},
           {"M486 AT1 S2", "T1_S2"},
           {"M486 A'star*box'", "STAR_BOX"},
           {"M486 a\"two  words\"", "TWO__WORDS"}}) {
    c = ok(line);
    EXPECT_FALSE(c.unknown) << line;
    EXPECT_EQ(c.subcode, kObjectName) << line;
    EXPECT_EQ(c.text, name) << line;
    EXPECT_FALSE(c.has_any_parameter()) << line;
  }
  // RepRapFirmware's one-line form: object S starts and is named.
  c = ok("M486 S3 A\"cube copy 3\"");
  EXPECT_EQ(c.subcode, kObjectName);
  EXPECT_EQ(c.text, "CUBE_COPY_3");
  EXPECT_EQ(c.get('S', -1), 3.0);
  c = ok("M486 S4 A\"\"");  // no name: S4
  EXPECT_EQ(c.subcode, kObjectStart);
  EXPECT_EQ(c.text, "4");
  c = ok("M486 S-1 A\"x\"");  // no object
  EXPECT_EQ(c.subcode, kObjectEnd);
  for (const char* nothing : {"M486 A", "M486", "M486 S1A"}) {
    c = ok(nothing);
    EXPECT_TRUE(c.unknown) << nothing;
    EXPECT_EQ(c.subcode, -1) << nothing;
  }
  for (const auto& [line, what] : std::vector<std::pair<std::string, std::string>>{
           {"M486 S", "S takes an object index"},
           {"M486 S1.5", "S takes an object index"},
           {"M486 S-2", "S takes an object index"},
           {"M486 P-1", "P takes an object index"},
           {"M486 T", "T takes an object index"},
           {"M486 S1 P2", "one of T, S, P and C per line"},
           {"M486 U1", "not supported"},
           {"M486 T3 Afoo", "goes on a line of its own or after S<index>"},
           {"M486 S1.5 Afoo", "goes on a line of its own or after S<index>"},
           {"M486 S-3 Afoo", "goes on a line of its own or after S<index>"}}) {
    auto bad = parse_line(line, SourceLocation{"t", 7, 0});
    ASSERT_FALSE(bad.ok()) << line;
    EXPECT_NE(bad.error().message.find(what), std::string::npos)
        << line << ": " << bad.error().message;
    EXPECT_EQ(bad.error().where.line, 7) << line;
  }
}

TEST(Parser, KlippersSetPressureAdvanceBecomesM900) {
  Command c = ok("SET_PRESSURE_ADVANCE ADVANCE=0.05 SMOOTH_TIME=0.03 ; comment");
  EXPECT_FALSE(c.unknown);
  EXPECT_TRUE(c.is('M', 900));
  EXPECT_EQ(c.text, "SET_PRESSURE_ADVANCE");
  EXPECT_DOUBLE_EQ(c.get('K'), 0.05);
  EXPECT_DOUBLE_EQ(c.get('S'), 0.03);
  c = ok("set_pressure_advance");  // a query: no values
  EXPECT_TRUE(c.is('M', 900));
  EXPECT_FALSE(c.has('K'));
  c = ok("M900 K0.1");
  EXPECT_FALSE(c.unknown);
  EXPECT_TRUE(c.text.empty());
  auto bad = parse_line("SET_PRESSURE_ADVANCE ADVANCE=0.1 ADVANCE=0.2", SourceLocation{"t", 3, 0});
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.error().where.column, 34);
  EXPECT_NE(bad.error().message.find("given twice"), std::string::npos);
  bad = parse_line("SET_PRESSURE_ADVANCE ADVANCE", SourceLocation{"t", 3, 0});
  ASSERT_FALSE(bad.ok());
  bad = parse_line("M900 K12", SourceLocation{"t", 3, 0});  // Marlin's range 0..10
  ASSERT_FALSE(bad.ok());
  bad = parse_line("M900 L0.2", SourceLocation{"t", 3, 0});  // the second slot: not supported
  ASSERT_FALSE(bad.ok());
  bad = parse_line("SET_VELOCITY_LIMIT VELOCITY=300", SourceLocation{"t", 3, 0});  // still refused
  ASSERT_FALSE(bad.ok());
}

TEST(Parser, UnknownCommandsParseAndAreFlagged) {
  Command c = ok("M572 S0.05");  // RepRapFirmware's pressure advance (feedloop: M900)
  EXPECT_TRUE(c.unknown);
  EXPECT_DOUBLE_EQ(c.get('S'), 0.05);
  c = ok("G29.1 Z0.2");
  EXPECT_TRUE(c.unknown);
  EXPECT_EQ(c.code, 29);
  EXPECT_EQ(c.subcode, 1);
  c = ok("M862.3 P \"MK3S\"");  // not G-code words: kept as text
  EXPECT_TRUE(c.unknown);
  EXPECT_EQ(c.text, "P \"MK3S\"");
  EXPECT_FALSE(ok("G1 X1").unknown);
}

// PrusaSlicer's start G-code for Prusa printers (MK3S, MK4): a firmware version check and a
// homing without the mesh levelling. Both once failed the whole line (a print job ended in error
// at line 3): "3.13.0" is not a number, and W was not one of G28's parameters.
TEST(Parser, PrusaFirmwaresStartLinesParse) {
  Command c = ok("M115 U3.13.0 ; tell the firmware the version");
  EXPECT_FALSE(c.unknown);
  EXPECT_EQ(c.text, "U3.13.0");
  c = ok("M115 U6.1.3+7898");
  EXPECT_EQ(c.text, "U6.1.3+7898");
  c = ok("M115");
  EXPECT_EQ(c.text, "");
  c = ok("G28 W ; home all without mesh bed level");
  EXPECT_TRUE(c.is('G', 28));
  EXPECT_TRUE(c.has('W'));
  EXPECT_FALSE(c.has('X'));
}

TEST(Parser, ErrorsCarryColumnAndMessage) {
  struct Case {
    const char* line;
    int column;
    const char* fragment;
  };
  const Case cases[] = {
      {"X10 Y20", 1, "before any command"},
      {"G1 X10 Q3", 8, "Q is not allowed"},
      {"G1 X1 X2", 7, "X given twice"},
      {"G90 G21", 5, "only one command per line"},
      {"G1 X", 4, "X needs a number"},
      {"G1 X-", 4, "bad number"},
      {"G1 X1.2.3", 8, "unexpected character '.'"},
      {"G1 X1 #", 7, "unexpected character '#'"},
      {"G1 X1 \xC3\xA9", 7, "unexpected byte 0xC3"},
      {"G", 1, "needs a code number"},
      {"  M104 S-1", 8, "between 0 and 1000"},
      // A host's non-finite number: named, not read as flags ("Xnan" is X, N, A, N).
      {"G1 Xnan Y1", 4, "X: 'nan' is not a number"},
      {"G1 X1 Yinf", 7, "Y: 'inf' is not a number"},
      {"G1 X-INF", 4, "X: '-INF' is not a number"},
      {"G1 X +Infinity", 4, "X: '+Infinity' is not a number"},
      {"M104 SNaN", 6, "S: 'NaN' is not a number"},
  };
  for (const Case& k : cases) {
    const Error e = err(k.line);
    EXPECT_EQ(e.where.column, k.column) << k.line << ": " << e.to_string();
    EXPECT_NE(e.message.find(k.fragment), std::string::npos) << k.line << ": " << e.message;
    EXPECT_EQ(e.where.source, "t.gcode");
    EXPECT_EQ(e.where.line, 7);
  }
  EXPECT_EQ(err("M104 S-1").to_string(),
            "t.gcode:7:6: M104 (set hotend temperature): S must be between 0 and 1000 (got -1)");
}

TEST(Parser, ReusedCommandIsClearedBetweenLines) {
  Command c;
  const SourceLocation where{"s", 1, 0};
  ASSERT_TRUE(parse_line("M117 text", where, c).ok());
  ASSERT_TRUE(parse_line("G1 X1 E2", where, c).ok());
  EXPECT_TRUE(c.text.empty());
  ASSERT_TRUE(parse_line("G1 Y3", where, c).ok());
  EXPECT_FALSE(c.has('X'));
  EXPECT_FALSE(c.has('E'));
  EXPECT_DOUBLE_EQ(c.get('X', -1.0), -1.0);
  EXPECT_FALSE(parse_line("G1 Q1", where, c).ok());
  EXPECT_TRUE(c.empty());  // nothing of a failed line survives
}

TEST(Parser, MegabyteLinesAreLinearAndSafe) {
  // A 2 MB comment, a 2 MB run of digits and a 2 MB run of letters: each parses or fails cleanly.
  const std::string comment = "G1 X1 ;" + std::string(2'000'000, 'x');
  EXPECT_DOUBLE_EQ(ok(comment).get('X'), 1.0);
  const std::string digits = "G1 X" + std::string(2'000'000, '0') + "1.5";
  EXPECT_DOUBLE_EQ(ok(digits).get('X'), 1.5);
  EXPECT_EQ(err("G1 X1" + std::string(2'000'000, '0')).where.column, 4);  // 1e2000000
  const std::string letters = "M998 " + std::string(2'000'000, 'A');
  const Command unknown = ok(letters);
  EXPECT_TRUE(unknown.unknown);
  EXPECT_EQ(unknown.text.size(), 2'000'000u);  // "A" twice -> not words -> kept as text
  const Error e = err("G1 " + std::string(2'000'000, 'X'));
  EXPECT_EQ(e.where.column, 5);  // the second X
}

}  // namespace
}  // namespace feedloop::gcode
