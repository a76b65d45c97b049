// Object labels: which object of the plate the G-code is printing, and which objects are
// excluded (Klipper's exclude_object; the slicer wraps each object's moves in
// EXCLUDE_OBJECT_START / _END, gcode/parser.cpp). The interpreter skips the moves of an
// excluded object (planner/interpreter.hpp). Names are upper-case (Klipper upper-cases them).
// An object labelled by its index (Marlin's M486 S<i>) may be given a name (PrusaSlicer's
// M486 A<name>): the lists hold the name from then on and the index stays its alias, so that
// M486 S<i> and M486 P<i> still reach it (resolve()).
// Bounded: at most kMaxObjects names each list; more are refused with an error by the caller.
// Owner: the planner thread (the interpreter); status() copies are for other threads.
#pragma once

#include <algorithm>
#include <cstddef>
#include <string>
#include <string_view>
#include <utility>
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
  // The name an index was given (name_current()), else `name` itself.
  std::string_view resolve(std::string_view name) const {
    for (const auto& [index, given] : aliases_)
      if (index == name) return given;
    return name;
  }
  // Names the current object; its former name (its index) becomes an alias of the new one. An
  // object excluded under either name stays excluded. False, nothing changed, when no object is
  // current, another defined object has the name, or the aliases are full.
  bool name_current(std::string_view name) {
    if (current_.empty() || name.empty()) return false;
    if (current_ == name) return true;
    if (contains(defined_, name)) return false;
    auto alias = std::find_if(aliases_.begin(), aliases_.end(),
                              [&](const auto& a) { return a.second == current_; });
    if (alias == aliases_.end()) {
      if (aliases_.size() >= kMaxObjects) return false;
      aliases_.emplace_back(current_, std::string(name));
    } else {
      alias->second.assign(name);
    }
    std::replace(defined_.begin(), defined_.end(), current_, std::string(name));
    const bool excluded = contains(excluded_, current_) || contains(excluded_, name);
    std::erase(excluded_, current_);
    std::erase(excluded_, std::string(name));
    if (excluded) excluded_.emplace_back(name);
    current_.assign(name);
    return true;
  }
  // EXCLUDE_OBJECT_DEFINE RESET=1: a new plate, nothing defined or excluded.
  void reset_all() {
    defined_.clear();
    excluded_.clear();
    current_.clear();
    aliases_.clear();
  }
  // EXCLUDE_OBJECT RESET=1: every object printed again.
  void reset_excluded() { excluded_.clear(); }

  // An object labelled by its index (M486 S<i>): its name is the index in decimal, as the
  // parser writes it for M486 S<i> alone (gcode/parser.cpp).
  static std::string index_name(double index) { return std::to_string(static_cast<int>(index)); }

  // Nothing defined, excluded or being printed: the G-code labels no objects.
  bool empty() const { return defined_.empty() && excluded_.empty() && current_.empty(); }
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
  std::vector<std::pair<std::string, std::string>> aliases_;  // index -> the name it was given
};

}  // namespace feedloop::planner
