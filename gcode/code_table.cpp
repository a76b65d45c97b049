// The table of known codes and their parameters. Semantics follow Marlin 2.x (the G-code reference
// at marlinfw.org and Marlin/src/gcode/**); where Marlin silently ignores nonsense (a negative
// temperature, a fan speed of 300) feedloop rejects the line instead, so nothing half-executes.
#include "gcode/code_table.hpp"

#include <array>
#include <limits>

namespace feedloop::gcode {
namespace {

using K = ParamRule::Kind;
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kMaxTempDegC = 1000.0;  // sanity bound only; the heater's max_temp is config's job
constexpr double kMaxIndex = 255.0;      // tool / fan / preset indices

constexpr ParamRule num(char l) { return {l, K::kNumber, -kInf, kInf}; }
constexpr ParamRule non_negative(char l) { return {l, K::kNumber, 0.0, kInf}; }
constexpr ParamRule positive(char l) { return {l, K::kNumber, 0.0, kInf, true}; }
constexpr ParamRule range(char l, double lo, double hi) { return {l, K::kNumber, lo, hi}; }
constexpr ParamRule index(char l) { return {l, K::kNumber, 0.0, kMaxIndex, false, true}; }
constexpr ParamRule flag(char l) { return {l, K::kFlag, -kInf, kInf}; }
constexpr ParamRule temp(char l) { return range(l, 0.0, kMaxTempDegC); }

// G0/G1 linear move: axes in the current units (G20/G21) and mode (G90/G91, M82/M83), F in
// units/min (> 0; F0 would stall the planner).
constexpr ParamRule kMove[] = {num('X'), num('Y'), num('Z'), num('E'), positive('F')};
// G2/G3 arc: I/J centre offsets or R radius, P = number of extra full circles.
constexpr ParamRule kArc[] = {num('X'), num('Y'), num('Z'), num('E'), num('I'), num('J'),
                              num('R'), positive('F'), {'P', K::kNumber, 0.0, 1e6, false, true}};
// G4 dwell: P milliseconds or S seconds (S wins when both are given, as in Marlin).
constexpr ParamRule kDwell[] = {non_negative('P'), non_negative('S')};
// G10 firmware retract: S1 = swap retract (tool change); Marlin reads S as a bool and ignores
// other words (Marlin/src/gcode/feature/fwretract/G10_G11.cpp). With P it is the temperature form
// hosts send for RepRapFirmware: P tool, S active, R standby temperature (the heaters' business,
// engine/machine.cpp).
constexpr ParamRule kRetract[] = {{'S', K::kFlagOrNumber, 0.0, kMaxTempDegC, false, false}, index('P'),
                                  temp('R')};
// G28 home: axis letters are flags (a value is ignored), O = only if not homed, L = restore
// levelling, R = raise before homing (mm), W = Prusa-Firmware's "without the mesh levelling that
// follows" (PrusaSlicer's MK3 / MK4 start G-code: `G28 W`; no levelling here to skip).
constexpr ParamRule kHome[] = {flag('X'), flag('Y'),         flag('Z'), flag('O'),
                               flag('L'), non_negative('R'), flag('W')};
// G92 set position.
constexpr ParamRule kSetPosition[] = {num('X'), num('Y'), num('Z'), num('E')};
// M73 progress: P percent, R minutes remaining; Q/S the same for silent mode (PrusaSlicer),
// C/D minutes to the next change.
constexpr ParamRule kProgress[] = {range('P', 0, 100), non_negative('R'), range('Q', 0, 100),
                                   non_negative('S'), non_negative('C'), non_negative('D')};
// M18/M84 disable steppers: axis flags, S = inactivity timeout in seconds (Marlin: M18 is an
// alias of M84; without S the axes are disabled and must be homed again, planner/interpreter.cpp).
constexpr ParamRule kMotorsOff[] = {flag('X'), flag('Y'), flag('Z'), flag('E'),
                                    non_negative('S')};
// M104/M109 hotend temperature: S target degC (M109: wait for heating), R (M109: wait for
// heating or cooling), T tool, B/F autotemp max and factor, I material preset.
constexpr ParamRule kHotend[] = {temp('S'), index('T'), temp('B'), non_negative('F'), index('I')};
constexpr ParamRule kHotendWait[] = {temp('S'), temp('R'), index('T'), temp('B'),
                                     non_negative('F'), index('I')};
// M105 report temperatures (some hosts add T).
constexpr ParamRule kReportTemp[] = {index('T')};
// M106 fan on: S speed 0..255, P fan index, T secondary speed, I material preset.
constexpr ParamRule kFanOn[] = {range('S', 0, 255), index('P'), range('T', 0, 255), index('I')};
constexpr ParamRule kFanOff[] = {index('P')};
// M155 temperature auto-report: S interval in seconds (0 off; Marlin allows up to 60).
constexpr ParamRule kAutoReport[] = {range('S', 0, 60)};
// M303 PID autotune: E heater (-1 the bed), S temperature, C cycles, U1 use the result.
constexpr ParamRule kAutotune[] = {{'E', K::kNumber, -1.0, kMaxIndex, false, true}, temp('S'),
                                   {'C', K::kNumber, 3.0, 20.0, false, true}, range('U', 0, 1)};
// M302 cold extrusion (Marlin): S the minimum extrusion temperature, P1 allow cold extrusion.
constexpr ParamRule kColdExtrude[] = {temp('S'), range('P', 0, 1)};
// M110 set the current line number (the N word after M110).
constexpr ParamRule kLineNumber[] = {{'N', K::kNumber, 0.0, 2147483647.0, false, true}};
// M114 report position: D detail, E stepper position, R real position.
constexpr ParamRule kReportPosition[] = {flag('D'), flag('E'), flag('R')};
// M140/M190 bed temperature: S target (M190 waits for heating), R (M190: heating or cooling).
constexpr ParamRule kBed[] = {temp('S'), index('I')};
constexpr ParamRule kBedWait[] = {temp('S'), temp('R'), index('I')};
// M201 max acceleration (units/s^2) and M203 max feedrate (units/s) per axis, T extruder.
constexpr ParamRule kPerAxisLimit[] = {positive('X'), positive('Y'), positive('Z'), positive('E'),
                                       index('T')};
// M204 accelerations (units/s^2): P printing, R retract, T travel; S (legacy) sets printing and
// travel at once.
constexpr ParamRule kAccel[] = {positive('P'), positive('R'), positive('T'), positive('S')};
// M205 advanced: X/Y/Z/E max jerk (units/s), J junction deviation (mm; Marlin accepts 0.01-0.3),
// S min printing feedrate, T min travel feedrate (units/s), B min segment time (us).
constexpr ParamRule kAdvanced[] = {non_negative('X'), non_negative('Y'), non_negative('Z'),
                                   non_negative('E'), range('J', 0.01, 0.3), non_negative('S'),
                                   non_negative('T'), non_negative('B')};
// M220 feedrate override percent (B backs up, R restores); M221 flow percent for extruder T.
// Marlin's SD-card commands (the daemon's job folder, docs/jobs.md): M20 L long names, T
// timestamps, F folders (listing flags); M24 S<byte> T<ms> (resume position, Marlin's
// POWER_LOSS_RECOVERY); M26 S byte position; M27 S auto-report seconds, C current file name.
constexpr ParamRule kFileList[] = {flag('L'), flag('T'), flag('F')};
constexpr ParamRule kFileStart[] = {non_negative('S'), non_negative('T')};
constexpr ParamRule kFilePosition[] = {{'S', K::kNumber, 0.0, 1e15, false, true}};
constexpr ParamRule kFileReport[] = {non_negative('S'), flag('C')};
constexpr ParamRule kFeedOverride[] = {range('S', 1, 1000), flag('B'), flag('R')};
constexpr ParamRule kFlowOverride[] = {range('S', 0, 1000), index('T')};
// M900 linear advance (Marlin gcode/feature/advance/M900.cpp): K factor in s (Marlin: 0..10), T
// extruder. L/S (EXTRA_LIN_ADVANCE_K slots) are not supported.
constexpr ParamRule kLinearAdvance[] = {range('K', 0, 10), index('T')};
// Tool change T<n>: F feedrate for the swap, S1 = no move.
constexpr ParamRule kToolChange[] = {{'F', K::kFlagOrNumber, 0.0, kInf, true},
                                     {'S', K::kFlagOrNumber, 0.0, 1.0, false, true}};

constexpr CodeRule kRules[] = {
    {'G', 0, "rapid linear move", kMove},
    {'G', 1, "linear move", kMove},
    {'G', 2, "clockwise arc", kArc, CrossCheck::kArc},
    {'G', 3, "counter-clockwise arc", kArc, CrossCheck::kArc},
    {'G', 4, "dwell", kDwell},
    {'G', 10, "retract", kRetract},
    {'G', 11, "recover (unretract)", {}},
    {'G', 20, "units: inches", {}},
    {'G', 21, "units: millimetres", {}},
    {'G', 28, "home axes", kHome},
    {'G', 90, "absolute positioning", {}},
    {'G', 91, "relative positioning", {}},
    {'G', 92, "set position", kSetPosition},
    {'M', 18, "disable steppers (M84)", kMotorsOff},
    {'M', 20, "list files", kFileList},
    {'M', 21, "init file storage", {}},
    {'M', 23, "select file", {}},
    {'M', 24, "start or resume file print", kFileStart},
    {'M', 25, "pause file print", {}},
    {'M', 26, "set file position", kFilePosition},
    {'M', 27, "report file print status", kFileReport},
    {'M', 32, "select and start file", {}},
    {'M', 73, "set print progress", kProgress},
    {'M', 82, "absolute extrusion", {}},
    {'M', 83, "relative extrusion", {}},
    {'M', 84, "disable steppers", kMotorsOff},
    {'M', 104, "set hotend temperature", kHotend},
    {'M', 105, "report temperatures", kReportTemp},
    {'M', 106, "fan on", kFanOn},
    {'M', 107, "fan off", kFanOff},
    {'M', 108, "break and continue (ends a heater wait)", {}},
    {'M', 109, "wait for hotend temperature", kHotendWait},
    {'M', 110, "set line number", kLineNumber},
    {'M', 112, "emergency stop", {}},
    {'M', 114, "report position", kReportPosition},
    {'M', 115, "firmware info", {}},
    {'M', 117, "display message", {}},
    {'M', 119, "report endstop states", {}},  // Marlin's M119 (docs/homing.md)
    {'M', 140, "set bed temperature", kBed},
    {'M', 155, "temperature auto-report", kAutoReport},
    {'M', 190, "wait for bed temperature", kBedWait},
    {'M', 201, "max acceleration", kPerAxisLimit},
    {'M', 203, "max feedrate", kPerAxisLimit},
    {'M', 204, "acceleration", kAccel},
    {'M', 205, "advanced motion settings", kAdvanced},
    {'M', 220, "feedrate override", kFeedOverride},
    {'M', 221, "flow override", kFlowOverride},
    {'M', 302, "cold extrusion", kColdExtrude},
    {'M', 303, "PID autotune", kAutotune},
    {'M', 400, "wait for moves to finish", {}},
    {'M', 524, "abort file print", {}},
    {'M', 900, "linear advance factor", kLinearAdvance},
    {'M', 999, "restart after a stop", {}},  // the daemon rebuilds the machine (docs/heaters.md)
};
constexpr CodeRule kToolRule{'T', 0, "select tool", kToolChange};

constexpr int kMaxG = 100;
constexpr int kMaxM = 1000;

struct Index {
  std::array<int8_t, kMaxG> g{};
  std::array<int8_t, kMaxM> m{};
};

constexpr Index build_index() {
  Index ix;
  ix.g.fill(-1);
  ix.m.fill(-1);
  for (int i = 0; i < static_cast<int>(std::size(kRules)); ++i) {
    if (kRules[i].letter == 'G') ix.g[kRules[i].code] = static_cast<int8_t>(i);
    else ix.m[kRules[i].code] = static_cast<int8_t>(i);
  }
  return ix;
}
constexpr Index kIndex = build_index();

}  // namespace

const CodeRule* find_code_rule(char letter, int code) {
  if (code < 0) return nullptr;
  int i = -1;
  if (letter == 'G' && code < kMaxG) i = kIndex.g[code];
  else if (letter == 'M' && code < kMaxM) i = kIndex.m[code];
  else if (letter == 'T' && code <= kMaxIndex) return &kToolRule;
  return i < 0 ? nullptr : &kRules[i];
}

bool is_text_command(char letter, int code) {
  if (letter != 'M') return false;
  switch (code) {
    case 23:   // select SD file
    case 28:   // start SD write
    case 30:   // delete SD file
    case 32:   // select and start SD file
    case 115:  // firmware info; Prusa-Firmware's M115 U<version> (a version check, not a number)
    case 117:  // display message
    case 118:  // serial print
    case 928:  // start SD logging
      return true;
    default:
      return false;
  }
}

std::span<const CodeRule> all_code_rules() { return kRules; }

}  // namespace feedloop::gcode
