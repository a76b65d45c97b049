// Shared helpers for the config tests: a minimal valid Cartesian config and text edits on it, and
// the 1-based line/column of a piece of text, so expected error locations follow the fixture.
#pragma once

#include <fstream>
#include <sstream>
#include <string>
#include <utility>

namespace feedloop::config::testing {

inline const char* kMinimal =
    "kinematics: cartesian\n"
    "axes:\n"
    "  x:\n"
    "    steps_per_mm: 80\n"
    "    encoder: {resolution_um: 0.49}\n"
    "    min_mm: 0\n"
    "    max_mm: 200\n"
    "    max_velocity_mm_s: 300\n"
    "    max_accel_mm_s2: 3000\n"
    "  y:\n"
    "    steps_per_mm: 80\n"
    "    min_mm: 0\n"
    "    max_mm: 200\n"
    "    max_velocity_mm_s: 300\n"
    "    max_accel_mm_s2: 3000\n"
    "  z:\n"
    "    steps_per_mm: 400\n"
    "    min_mm: 0\n"
    "    max_mm: 180\n"
    "    max_velocity_mm_s: 10\n"
    "    max_accel_mm_s2: 100\n"
    "  e:\n"
    "    steps_per_mm: 96\n"
    "    max_velocity_mm_s: 60\n"
    "    max_accel_mm_s2: 3000\n"
    "model:\n"
    "  gantry:\n"
    "    x:\n"
    "      m1_kg: 0.130\n"
    "      m2_kg: 0.45\n"
    "      k1_n_per_m: 355e3\n"
    "      k2_n_per_m: 110e3\n"
    "      c1_ns_per_m: 2100\n"
    "      c2_ns_per_m: 112\n"
    "mcus:\n"
    "  - name: mcu_xy\n"
    "    axes: [x, y]\n"
    "    transport: mock\n"
    "  - name: mcu_z\n"
    "    axes: [z]\n"
    "    transport: mock\n"
    "  - name: mcu_e\n"
    "    axes: [e]\n"
    "    transport: mock\n";

// `text` with the first occurrence of `from` replaced by `to` (the test fails loudly if absent).
inline std::string edit(std::string text, const std::string& from, const std::string& to) {
  const std::size_t at = text.find(from);
  if (at == std::string::npos) return "EDIT TARGET NOT FOUND: " + from;
  return text.replace(at, from.size(), to);
}

struct Pos {
  int line = 0;
  int column = 0;
};

// 1-based line and column of the first occurrence of `needle` (plus `offset` characters).
inline Pos pos_of(const std::string& text, const std::string& needle, std::size_t offset = 0) {
  const std::size_t at = text.find(needle);
  if (at == std::string::npos) return {};
  const std::size_t target = at + offset;
  Pos p{1, 1};
  for (std::size_t i = 0; i < target; ++i) {
    if (text[i] == '\n') {
      ++p.line;
      p.column = 1;
    } else {
      ++p.column;
    }
  }
  return p;
}

inline std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

inline std::string example_path(const std::string& name) {
  return std::string(FEEDLOOP_SOURCE_DIR) + "/config/examples/" + name;
}

}  // namespace feedloop::config::testing
