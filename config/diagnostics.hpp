// Collects every problem found while loading a config, each with file:line:column, so a user sees
// all of them at once instead of fixing one per run.
#pragma once

#include <string>
#include <utility>
#include <string_view>
#include <vector>

#include "core/result.hpp"

namespace YAML {
class Mark;
}

namespace feedloop::config {

class Diagnostics {
 public:
  explicit Diagnostics(std::string source) : source_(std::move(source)) {}

  // yaml-cpp marks are 0-based; locations in messages are 1-based.
  void add(const YAML::Mark& mark, std::string message);
  void add(int line, int column, std::string message);

  // Unknown keys are reported at the end (resolve_unknown_keys), once every section has said
  // which keys it knows: a key that is valid in another section gets "(it belongs in planner)".
  void note_known_key(const std::string& section, const std::string& key);
  void add_unknown_key(const YAML::Mark& mark, const std::string& section, const std::string& key,
                       const std::string& suggestion);
  void resolve_unknown_keys();

  bool empty() const { return errors_.empty() && unknown_.empty(); }
  const std::vector<Error>& errors() const { return errors_; }
  const std::string& source() const { return source_; }

  // One Error for all problems: `where` is the first problem's location and the message continues
  // with one "file:line:col: message" line per further problem, so Error::to_string() prints every
  // problem on its own line.
  Error combined() const;

 private:
  struct Unknown {
    int line, column;
    std::string section, key, suggestion;
  };
  std::string source_;
  std::vector<Error> errors_;
  std::vector<Unknown> unknown_;
  std::vector<std::pair<std::string, std::string>> known_;  // (key, section)
};

// Levenshtein distance, for "did you mean" suggestions.
std::size_t edit_distance(std::string_view a, std::string_view b);

// The closest candidate to `word` if it is close enough to be a plausible typo, else "".
std::string closest_match(std::string_view word, const std::vector<std::string>& candidates);

}  // namespace feedloop::config
