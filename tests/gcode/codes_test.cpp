// Every G/M code the front end validates: a typical line with its parameters, and the lines that
// its validation must reject (with the column of the offending word).
#include <gtest/gtest.h>

#include <map>
#include <set>
#include <string>
#include <vector>

#include "gcode/code_table.hpp"
#include "gcode/parser.hpp"

namespace feedloop::gcode {
namespace {

struct Valid {
  const char* line;
  char letter;
  int code;
  std::map<char, double> values;  // parameters with a number
  std::string flags = "";         // parameters given as bare letters
};

const std::vector<Valid>& valid_cases() {
  static const std::vector<Valid> cases = {
      {"G0 X1 Y2 Z3 F6000", 'G', 0, {{'X', 1}, {'Y', 2}, {'Z', 3}, {'F', 6000}}},
      {"G1 X-1.5 Y2 Z0.2 E0.0333 F1800",
       'G',
       1,
       {{'X', -1.5}, {'Y', 2}, {'Z', 0.2}, {'E', 0.0333}, {'F', 1800}}},
      {"G2 X10 Y0 I5 J0 E1.2 F1200",
       'G',
       2,
       {{'X', 10}, {'Y', 0}, {'I', 5}, {'J', 0}, {'E', 1.2}, {'F', 1200}}},
      {"G3 X0 Y10 R5 P1", 'G', 3, {{'X', 0}, {'Y', 10}, {'R', 5}, {'P', 1}}},
      {"G4 P250", 'G', 4, {{'P', 250}}},
      {"G4 S1.5", 'G', 4, {{'S', 1.5}}},
      {"G10", 'G', 10, {}},
      {"G10 S1", 'G', 10, {{'S', 1}}},
      {"G11", 'G', 11, {}},
      {"G20", 'G', 20, {}},
      {"G21", 'G', 21, {}},
      {"G28", 'G', 28, {}},
      {"G28 X Y", 'G', 28, {}, "XY"},
      {"G28 X0 Z0", 'G', 28, {{'X', 0}, {'Z', 0}}},
      {"G28 O R10", 'G', 28, {{'R', 10}}, "O"},
      {"G90", 'G', 90, {}},
      {"G91", 'G', 91, {}},
      {"G92 E0", 'G', 92, {{'E', 0}}},
      {"G92 X10 Y20 Z0.3 E-2", 'G', 92, {{'X', 10}, {'Y', 20}, {'Z', 0.3}, {'E', -2}}},
      {"M73 P42 R13", 'M', 73, {{'P', 42}, {'R', 13}}},
      {"M73 Q0 S13", 'M', 73, {{'Q', 0}, {'S', 13}}},
      {"M82", 'M', 82, {}},
      {"M83", 'M', 83, {}},
      {"M84", 'M', 84, {}},
      {"M84 X Y E", 'M', 84, {}, "XYE"},
      {"M84 S600", 'M', 84, {{'S', 600}}},
      {"M18 Z", 'M', 18, {}, "Z"},  // Marlin: M18 is M84
      {"M104 S215", 'M', 104, {{'S', 215}}},
      {"M104 T1 S0", 'M', 104, {{'T', 1}, {'S', 0}}},
      {"M105", 'M', 105, {}},
      {"M106 S255", 'M', 106, {{'S', 255}}},
      {"M106 P1 S0", 'M', 106, {{'P', 1}, {'S', 0}}},
      {"M107", 'M', 107, {}},
      {"M107 P1", 'M', 107, {{'P', 1}}},
      {"M109 S215", 'M', 109, {{'S', 215}}},
      {"M109 R180", 'M', 109, {{'R', 180}}},
      {"M110 N100", 'M', 110, {{'N', 100}}},
      {"M112", 'M', 112, {}},
      {"M114", 'M', 114, {}},
      {"M114 D", 'M', 114, {}, "D"},
      {"M115", 'M', 115, {}},
      {"M117 Hello", 'M', 117, {}},
      {"M119", 'M', 119, {}},
      {"M140 S60", 'M', 140, {{'S', 60}}},
      {"M190 S60", 'M', 190, {{'S', 60}}},
      {"M155 S2", 'M', 155, {{'S', 2}}},
      {"M303 E-1 S60 C5 U1", 'M', 303, {{'E', -1}, {'S', 60}, {'C', 5}, {'U', 1}}},
      {"M190 R40", 'M', 190, {{'R', 40}}},
      {"M201 X3000 Y3000 Z100 E5000",
       'M',
       201,
       {{'X', 3000}, {'Y', 3000}, {'Z', 100}, {'E', 5000}}},
      {"M203 X300 Y300 Z12 E120", 'M', 203, {{'X', 300}, {'Y', 300}, {'Z', 12}, {'E', 120}}},
      {"M204 P3000 R3000 T3000", 'M', 204, {{'P', 3000}, {'R', 3000}, {'T', 3000}}},
      {"M204 S1500", 'M', 204, {{'S', 1500}}},
      {"M205 X8 Y8 Z0.4 E4.5", 'M', 205, {{'X', 8}, {'Y', 8}, {'Z', 0.4}, {'E', 4.5}}},
      {"M205 J0.013 S0 T0 B20000", 'M', 205, {{'J', 0.013}, {'S', 0}, {'T', 0}, {'B', 20000}}},
      {"M220 S150", 'M', 220, {{'S', 150}}},
      {"M18 X E", 'M', 18, {}, "XE"},
      {"M20 L", 'M', 20, {}, "L"},
      {"M21", 'M', 21, {}},
      {"M23 benchy.gcode", 'M', 23, {}},
      {"M24", 'M', 24, {}},
      {"M25", 'M', 25, {}},
      {"M26 S1024", 'M', 26, {{'S', 1024}}},
      {"M27 C", 'M', 27, {}, "C"},
      {"M32 !benchy.gcode#", 'M', 32, {}},
      {"M524", 'M', 524, {}},
      {"M999", 'M', 999, {}},
      {"M900 K0.05 T0", 'M', 900, {{'K', 0.05}, {'T', 0}}},
      {"M220 B", 'M', 220, {}, "B"},
      {"M221 S95 T0", 'M', 221, {{'S', 95}, {'T', 0}}},
      {"M400", 'M', 400, {}},
      {"M302 S150 P1", 'M', 302, {{'S', 150}, {'P', 1}}},
      {"M108", 'M', 108, {}},
  };
  return cases;
}

TEST(Codes, EveryListedCodeParsesWithItsParameters) {
  for (const Valid& v : valid_cases()) {
    auto r = parse_line(v.line, SourceLocation{"codes", 1, 0});
    ASSERT_TRUE(r.ok()) << v.line << ": " << r.error().to_string();
    const Command& c = r.value();
    EXPECT_TRUE(c.is(v.letter, v.code)) << v.line;
    EXPECT_FALSE(c.unknown) << v.line;
    for (char p = 'A'; p <= 'Z'; ++p) {
      const bool want_value = v.values.count(p) > 0;
      const bool want_flag = v.flags.find(p) != std::string::npos;
      EXPECT_EQ(c.has(p), want_value || want_flag) << v.line << " letter " << p;
      EXPECT_EQ(c.has_value(p), want_value) << v.line << " letter " << p;
      if (want_value) {
        EXPECT_DOUBLE_EQ(c.get(p), v.values.at(p)) << v.line << " letter " << p;
      }
    }
  }
}

TEST(Codes, TheTableCoversExactlyTheIssueList) {
  const std::set<std::string> listed = {
      "G0", "G1", "G2", "G3", "G4", "G10", "G11", "G20", "G21", "G28", "G90", "G91", "G92", "M18",
      "M73", "M82", "M83", "M84", "M104", "M105", "M106", "M107", "M109", "M110", "M112", "M114",
      "M115", "M117", "M140", "M190", "M201", "M203", "M204", "M205", "M220", "M221", "M400",
      "M155", "M303",
      // issue 16 (print jobs): M18 and Marlin's SD-card commands
      "M18", "M20", "M21", "M23", "M24", "M25", "M26", "M27", "M32", "M524",
      // issue 16 (pressure advance): Marlin's linear advance factor
      "M900",
      // issue 16 (homing): Marlin's endstop report
      "M119",
      // issue 16 (thermal faults): Marlin's restart after a stop
      "M999",
      // cold extrusion (docs/heaters.md): Marlin's M302
      "M302",
      // Marlin's break and continue: ends a heater wait (docs/heaters.md)
      "M108"};
  std::set<std::string> table, tested;
  for (const CodeRule& r : all_code_rules()) table.insert(r.letter + std::to_string(r.code));
  for (const Valid& v : valid_cases()) tested.insert(v.letter + std::to_string(v.code));
  EXPECT_EQ(table, listed);
  EXPECT_EQ(tested, listed);
}

struct Invalid {
  const char* line;
  int column;
  const char* fragment;
};

TEST(Codes, ValidationRejectsWithColumn) {
  const Invalid cases[] = {
      {"G0 X1 S3", 7, "S is not allowed"},
      {"G1 F0", 4, "F must be > 0"},
      {"G1 F-100", 4, "F must be > 0"},
      {"G1 X", 4, "X needs a number"},
      {"G2 X10 Y0", 1, "needs I/J"},
      {"G3 X1 I1 R2", 10, "not both"},
      {"G2 X1 I1 P1.5", 10, "whole number"},
      {"G4 P-5", 4, ">= 0"},
      {"G4 X1", 4, "X is not allowed"},
      {"G10 P0 S-5", 8, "between 0 and 1000"},  // S2 is accepted: Marlin reads S as a bool
      {"G11 S1", 5, "takes none"},
      {"G20 X1", 5, "takes none"},
      {"G21 Y", 5, "takes none"},
      {"G28 R-1", 5, "R must be >= 0"},
      {"G28 E", 5, "E is not allowed"},
      {"G90 X0", 5, "takes none"},
      {"G91 Z", 5, "takes none"},
      {"G92 E", 5, "E needs a number"},
      {"G92 F100", 5, "F is not allowed"},
      {"M73 P101", 5, "between 0 and 100"},
      {"M73 R-1", 5, ">= 0"},
      {"M82 E1", 5, "takes none"},
      {"M83 S", 5, "takes none"},
      {"M84 S-1", 5, ">= 0"},
      {"M84 F1", 5, "F is not allowed"},
      {"M104 S-10", 6, "between 0 and 1000"},
      {"M104 S1200", 6, "between 0 and 1000"},
      {"M104 T0.5 S200", 6, "whole number"},
      {"M104 S", 6, "S needs a number"},
      {"M105 S1", 6, "S is not allowed"},
      {"M106 S256", 6, "between 0 and 255"},
      {"M106 S-1", 6, "between 0 and 255"},
      {"M106 P1.5", 6, "whole number"},
      {"M107 S0", 6, "S is not allowed"},
      {"M109 S-1", 6, "between 0 and 1000"},
      {"M109 R2000", 6, "between 0 and 1000"},
      {"M110 N-1", 6, "between 0 and 2147483647"},
      {"M110 N1.5", 6, "whole number"},
      {"M112 X", 6, "takes none"},
      {"M114 X", 6, "X is not allowed"},
      {"M400 P1", 6, "takes none"},
      {"M140 S-5", 6, "between 0 and 1000"},
      {"M190 S5000", 6, "between 0 and 1000"},
      {"M201 X0", 6, "X must be > 0"},
      {"M201 Y-3000", 6, "Y must be > 0"},
      {"M203 E0", 6, "E must be > 0"},
      {"M204 P0", 6, "P must be > 0"},
      {"M204 S-1", 6, "S must be > 0"},
      {"M204 X100", 6, "X is not allowed"},
      {"M205 J0.5", 6, "between 0.01 and 0.3"},
      {"M205 J0.001", 6, "between 0.01 and 0.3"},
      {"M205 X-1", 6, "X must be >= 0"},
      {"M205 Q1", 6, "Q is not allowed"},
      {"M220 S0", 6, "between 1 and 1000"},
      {"M221 S-5", 6, "between 0 and 1000"},
      {"M221 T1.5", 6, "whole number"},
      {"M400 S1", 6, "takes none"},
  };
  for (const Invalid& k : cases) {
    auto r = parse_line(k.line, SourceLocation{"codes", 3, 0});
    ASSERT_FALSE(r.ok()) << k.line << " should fail";
    EXPECT_EQ(r.error().where.column, k.column) << k.line << ": " << r.error().to_string();
    EXPECT_NE(r.error().message.find(k.fragment), std::string::npos)
        << k.line << ": " << r.error().message;
    EXPECT_EQ(r.error().where.line, 3);
  }
}

TEST(Codes, M204AndM205MeaningsAreDocumentedInTheTable) {
  // M204: P printing, R retract, T travel, S legacy (print + travel); M205: X/Y/Z/E jerk, J
  // junction deviation, S/T min feedrates, B min segment time. The letters are exactly these.
  const CodeRule* m204 = find_code_rule('M', 204);
  const CodeRule* m205 = find_code_rule('M', 205);
  ASSERT_NE(m204, nullptr);
  ASSERT_NE(m205, nullptr);
  std::string l204, l205;
  for (const ParamRule& p : m204->params) l204 += p.letter;
  for (const ParamRule& p : m205->params) l205 += p.letter;
  EXPECT_EQ(l204, "PRTS");
  EXPECT_EQ(l205, "XYZEJSTB");
  EXPECT_EQ(find_code_rule('M', 998), nullptr);
  EXPECT_EQ(find_code_rule('G', 29), nullptr);
  EXPECT_EQ(find_code_rule('G', -1), nullptr);
}

}  // namespace
}  // namespace feedloop::gcode
