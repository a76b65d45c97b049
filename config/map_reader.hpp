// Typed, located reading of one YAML mapping. Every read checks the type, the unit (from the key's
// suffix, see units.hpp) and the range, and reports problems to Diagnostics with the line and
// column of the offending node; finish() reports keys nobody asked for, with a "did you mean".
// Readers never throw and never stop at the first problem.
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "config/diagnostics.hpp"

namespace feedloop::config {

enum class Need { optional, required };

// Allowed interval for a number, in the key's own unit.
struct Range {
  double min = -std::numeric_limits<double>::infinity();
  double max = std::numeric_limits<double>::infinity();
  bool min_open = false;  // true: value must be > min
  bool max_open = false;  // true: value must be < max

  static Range any() { return {}; }
  static Range positive() { return {0.0, std::numeric_limits<double>::infinity(), true, false}; }
  static Range non_negative() { return {0.0, std::numeric_limits<double>::infinity(), false, false}; }
  static Range closed(double lo, double hi) { return {lo, hi, false, false}; }
  static Range open_closed(double lo, double hi) { return {lo, hi, true, false}; }
  static Range open(double lo, double hi) { return {lo, hi, true, true}; }
};

class MapReader {
 public:
  // `node` may be absent or null (an empty mapping); anything else but a mapping is reported.
  // `path` names the mapping in messages ("axes.x"); `where` locates it when it is absent.
  MapReader(const YAML::Node& node, std::string path, Diagnostics& diag, const YAML::Mark& where);

  const std::string& path() const { return path_; }
  const YAML::Mark& mark() const { return mark_; }
  bool present() const { return present_; }
  bool has(std::string_view key) const;
  // Marks `key` as known and returns its value node (an undefined node when absent).
  YAML::Node get(std::string_view key);
  YAML::Mark key_mark(std::string_view key) const;  // the mapping's mark when absent
  std::string key_path(std::string_view key) const;
  // Keys in document order (duplicates removed).
  std::vector<std::string> keys() const;

  // Each returns true when a valid value was stored in `out` (left untouched otherwise).
  bool number(std::string_view key, double& out, Range range, Need need = Need::optional);
  bool integer(std::string_view key, std::int64_t& out, std::int64_t min, std::int64_t max,
               Need need = Need::optional);
  template <class I>
  bool integer_as(std::string_view key, I& out, std::int64_t min, std::int64_t max,
                  Need need = Need::optional) {
    std::int64_t v = 0;
    if (!integer(key, v, min, max, need)) return false;
    out = static_cast<I>(v);
    return true;
  }
  bool boolean(std::string_view key, bool& out, Need need = Need::optional);
  bool string(std::string_view key, std::string& out, Need need = Need::optional);
  bool string_list(std::string_view key, std::vector<std::string>& out, Need need = Need::optional);
  template <class E>
  bool choice(std::string_view key, E& out, const std::vector<std::pair<std::string, E>>& options,
              Need need = Need::optional) {
    std::string text;
    if (!string(key, text, need)) return false;
    std::vector<std::string> names;
    for (const auto& [name, value] : options) {
      if (name == text) {
        out = value;
        return true;
      }
      names.push_back(name);
    }
    report_bad_choice(key, text, names);
    return false;
  }

  // A nested mapping (absent or null: an empty reader; required: reported when absent).
  MapReader sub(std::string_view key, Need need = Need::optional);

  // Reports every key that no read asked for.
  void finish();

 private:
  struct Entry {
    std::string key;
    YAML::Node key_node;
    YAML::Node value;
    bool used = false;
  };
  const Entry* find(std::string_view key) const;
  void note(std::string_view key);  // remembers a key the schema knows, for suggestions
  // Shared front of the typed readers: absent/required/null handling. Returns the scalar node or
  // an undefined node when there is nothing to read.
  YAML::Node scalar(std::string_view key, Need need, const char* what);
  void report_bad_choice(std::string_view key, const std::string& got,
                         const std::vector<std::string>& names);

  std::string path_;
  Diagnostics* diag_;
  YAML::Mark mark_;
  bool present_ = false;
  std::vector<Entry> entries_;
  std::vector<std::string> asked_;  // every key the schema asked about, present or not
};

// "a mapping", "a list", "a value" or "nothing", for messages.
std::string node_kind(const YAML::Node& node);

// Number with an optional unit: "3000", "3000 mm/s^2", "-212.1 1/s". Returns false when `text` does
// not start with a finite number. `unit` receives the rest (trimmed, maybe empty).
bool split_number(std::string_view text, double& value, std::string& unit);

// Shortest text that reads back as exactly `v` (std::to_chars).
std::string format_number(double v);

}  // namespace feedloop::config
