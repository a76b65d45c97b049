// Helpers for the planner tests: machine configs matching the corpus profiles, a sink that
// records everything the planner emits, and reading corpus files through gcode/parser.
#pragma once

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "gcode/parser.hpp"
#include "planner/interpreter.hpp"
#include "planner/kinematics.hpp"
#include "planner/lookahead.hpp"

namespace feedloop::planner::test {

// Cartesian machine of profiles/cart220.ini (220 x 220 bed, limits M201/M203 of the corpus).
inline PlannerConfig cartesian_config() {
  PlannerConfig c;
  c.kinematics = KinematicsKind::cartesian;
  c.min_position_mm = {0.0, 0.0, 0.0, -1e12};
  c.max_position_mm = {220.0, 220.0, 250.0, 1e12};
  c.allow_moves_before_homing = true;  // most tests never home (homing_state_test.cpp does)
  return c;
}

// Canonical delta (DESIGN.md) with the 270 mm bed of profiles/delta270.ini.
inline PlannerConfig delta_config() {
  PlannerConfig c;
  c.kinematics = KinematicsKind::delta;
  c.min_position_mm = {-135.0, -135.0, 0.0, -1e12};
  c.max_position_mm = {135.0, 135.0, 300.0, 1e12};
  c.home_position_mm = {0.0, 0.0, 300.0, 0.0};
  c.max_axis_velocity_mm_s = {300.0, 300.0, 300.0, 120.0};
  c.max_axis_accel_mm_s2 = {3000.0, 3000.0, 3000.0, 5000.0};
  c.allow_moves_before_homing = true;
  return c;
}

struct Recorder : MoveSink {
  std::vector<PlannedMove> moves;
  std::vector<PlannerEvent> events;
  std::vector<uint64_t> added_at_emit;  // planner->moves_added() when each move was emitted
  const Planner* planner = nullptr;
  void on_move(const PlannedMove& m) override {
    moves.push_back(m);
    added_at_emit.push_back(planner ? planner->moves_added() : 0);
  }
  void on_event(const PlannerEvent& e) override { events.push_back(e); }
};

// Interpreter + planner + recorder in one object.
struct Rig {
  PlannerConfig cfg;
  std::unique_ptr<Kinematics> kin;
  Recorder rec;
  Planner planner;
  Interpreter interp;
  explicit Rig(const PlannerConfig& c)
      : cfg(c), kin(make_kinematics(c)), planner(c, rec), interp(c, *kin, planner) {
    rec.planner = &planner;
  }
  Status run(const std::string& line) {
    Result<gcode::Command> c = gcode::parse_line(line, {"test", 1, 0});
    if (!c) return c.error();
    return interp.execute(*c);
  }
};

inline std::string corpus_dir() { return std::string(FEEDLOOP_SHARED_DIR) + "/gcode"; }

inline std::vector<std::string> corpus_files() {
  std::vector<std::string> out;
  std::error_code ec;
  if (!std::filesystem::is_directory(corpus_dir(), ec)) return out;
  for (const auto& e : std::filesystem::directory_iterator(corpus_dir(), ec)) {
    if (e.path().extension() == ".gcode") out.push_back(e.path().string());
  }
  std::sort(out.begin(), out.end());
  return out;
}

// Parses a whole file; parse errors are counted (the corpus has none).
inline std::vector<gcode::Command> read_commands(const std::string& path, int* parse_errors) {
  std::vector<gcode::Command> out;
  std::ifstream in(path);
  std::string line;
  SourceLocation where{std::filesystem::path(path).filename().string(), 0, 0};
  gcode::Command cmd;
  while (std::getline(in, line)) {
    ++where.line;
    if (!gcode::parse_line(line, where, cmd)) {
      ++*parse_errors;
      continue;
    }
    if (!cmd.empty()) out.push_back(cmd);
  }
  return out;
}

}  // namespace feedloop::planner::test
