// Object labels: which object of the plate the G-code is printing, and which objects are
// excluded (Klipper's exclude_object; the slicer wraps each object's moves in
// EXCLUDE_OBJECT_START / _END, gcode/parser.cpp). The interpreter skips the moves of an
// excluded object (planner/interpreter.hpp). Names are upper-case (Klipper upper-cases them).
// Bounded: at most kMaxObjects names each list; more are refused with an error by the caller.
// Owner: the planner thread (the interpreter); status() copies are for other threads.
#pragma once

#include <algorithm>
#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace feedloop::planner {

class ObjectLabels {
 public:
  static constexpr size_t kMaxObjects = 1024;

  // False when the list is full (the name is not added).
  bool define(std::string_view name) { return add(defined_, name); }
  // False (and nothing changed) when the list is full.
  bool start(std::string_view name) {
    if (!add(defined_, name)) return false;
    current_.assign(name);
    return true;
  }
  void end() { current_.clear(); }
  bool exclude(std::string_view name) { return add(excluded_, name); }
  // EXCLUDE_OBJECT_DEFINE RESET=1: a new plate, nothing defined or excluded.
  void reset_all() {
    defined_.clear();
    excluded_.clear();
    current_.clear();
  }
  // EXCLUDE_OBJECT RESET=1: every object printed again.
  void reset_excluded() { excluded_.clear(); }

  // The moves of the current object are skipped.
  bool excluding() const { return !current_.empty() && contains(excluded_, current_); }
  const std::string& current() const { return current_; }
  const std::vector<std::string>& defined() const { return defined_; }
  const std::vector<std::string>& excluded() const { return excluded_; }

 private:
  static bool contains(const std::vector<std::string>& v, std::string_view name) {
    return std::find(v.begin(), v.end(), name) != v.end();
  }
  static bool add(std::vector<std::string>& v, std::string_view name) {
    if (contains(v, name)) return true;
    if (v.size() >= kMaxObjects) return false;
    v.emplace_back(name);
    return true;
  }

  std::vector<std::string> defined_, excluded_;
  std::string current_;
};

}  // namespace feedloop::planner
