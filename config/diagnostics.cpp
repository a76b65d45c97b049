// Problem collection and typo suggestions for config loading (see diagnostics.hpp).
#include "config/diagnostics.hpp"

#include <yaml-cpp/mark.h>

#include <algorithm>  // min, sort
#include <cctype>     // tolower

namespace feedloop::config {

void Diagnostics::add(const YAML::Mark& mark, std::string message) {
  if (mark.is_null()) {
    add(0, 0, std::move(message));
  } else {
    add(mark.line + 1, mark.column + 1, std::move(message));
  }
}

void Diagnostics::add(int line, int column, std::string message) {
  errors_.push_back(Error{std::move(message), SourceLocation{source_, line, column}});
}

void Diagnostics::note_known_key(const std::string& section, const std::string& key) {
  known_.emplace_back(key, section);
}

void Diagnostics::add_unknown_key(const YAML::Mark& mark, const std::string& section,
                                  const std::string& key, const std::string& suggestion) {
  unknown_.push_back(Unknown{mark.is_null() ? 0 : mark.line + 1, mark.is_null() ? 0 : mark.column + 1,
                             section, key, suggestion});
}

void Diagnostics::resolve_unknown_keys() {
  for (const Unknown& u : unknown_) {
    std::string msg = "unknown key '" + u.key + "' in " +
                      (u.section.empty() ? std::string("the config") : u.section);
    // Valid elsewhere? Name up to two sections that know it; else suggest a near key.
    std::vector<std::string> homes;
    for (const auto& [key, section] : known_) {
      const std::string home = section.empty() ? std::string("the top level") : section;
      if (key == u.key && section != u.section &&
          std::find(homes.begin(), homes.end(), home) == homes.end())
        homes.push_back(home);
    }
    if (!homes.empty()) {
      msg += " (it belongs in " + homes[0] + (homes.size() > 1 ? " or " + homes[1] : "") + ")";
    } else if (!u.suggestion.empty()) {
      msg += " (did you mean '" + u.suggestion + "'?)";
    }
    add(u.line, u.column, std::move(msg));
  }
  unknown_.clear();
}

Error Diagnostics::combined() const {
  if (errors_.empty()) return Error{"no problems", SourceLocation{source_, 0, 0}};
  // Problems sorted by position read best; stable so equal positions keep discovery order.
  std::vector<Error> sorted = errors_;
  std::stable_sort(sorted.begin(), sorted.end(), [](const Error& a, const Error& b) {
    return std::pair(a.where.line, a.where.column) < std::pair(b.where.line, b.where.column);
  });
  Error out = sorted.front();
  for (std::size_t i = 1; i < sorted.size(); ++i) out.message += "\n" + sorted[i].to_string();
  return out;
}

std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const bool same = std::tolower(static_cast<unsigned char>(a[i - 1])) ==
                        std::tolower(static_cast<unsigned char>(b[j - 1]));
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (same ? 0 : 1)});
    }
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

std::string closest_match(std::string_view word, const std::vector<std::string>& candidates) {
  std::string best;
  std::size_t best_d = static_cast<std::size_t>(-1);
  for (const std::string& c : candidates) {
    const std::size_t d = edit_distance(word, c);
    if (d < best_d) best_d = d, best = c;
  }
  // Plausible typo: at most a third of the word wrong (and at least one edit allowed).
  const std::size_t limit = std::max<std::size_t>(1, std::max(word.size(), best.size()) / 3);
  return best_d <= limit ? best : std::string();
}

}  // namespace feedloop::config
