// Typed, located reading of one YAML mapping (see map_reader.hpp).
#include "config/map_reader.hpp"

#include <charconv>  // from_chars, to_chars
#include <cmath>     // isfinite, floor

#include "config/units.hpp"

namespace feedloop::config {
namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

std::string range_text(const Range& r) {
  const bool has_min = std::isfinite(r.min), has_max = std::isfinite(r.max);
  if (has_min && has_max)
    return std::string("in ") + (r.min_open ? "(" : "[") + format_number(r.min) + ", " +
           format_number(r.max) + (r.max_open ? ")" : "]");
  if (has_min) return std::string(r.min_open ? "> " : ">= ") + format_number(r.min);
  if (has_max) return std::string(r.max_open ? "< " : "<= ") + format_number(r.max);
  return "finite";
}

std::string with_article(const std::string& noun) {
  const bool vowel = !noun.empty() && std::string_view("aeiou").find(noun[0]) != std::string_view::npos;
  return (vowel ? "an " : "a ") + noun;
}

bool in_range(double v, const Range& r) {
  if (r.min_open ? !(v > r.min) : !(v >= r.min)) return false;
  if (r.max_open ? !(v < r.max) : !(v <= r.max)) return false;
  return true;
}

}  // namespace

std::string node_kind(const YAML::Node& node) {
  if (!node.IsDefined() || node.IsNull()) return "nothing";
  if (node.IsMap()) return "a mapping";
  if (node.IsSequence()) return "a list";
  // A long scalar (a whole file that is not YAML mappings reads as one) is cut: the location says
  // where it starts.
  constexpr size_t kShown = 60;
  const std::string& text = node.Scalar();
  if (text.size() <= kShown) return "'" + text + "'";
  size_t cut = kShown;  // not inside a UTF-8 sequence
  while (cut > 0 && (static_cast<unsigned char>(text[cut]) & 0xC0) == 0x80) --cut;
  return "'" + text.substr(0, cut) + "...' (" + std::to_string(text.size()) + " bytes)";
}

bool split_number(std::string_view text, double& value, std::string& unit) {
  text = trim(text);
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  const char* begin = text.data();
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(begin, end, value, std::chars_format::general);
  if (ec != std::errc() || !std::isfinite(value)) return false;
  // The rest is the unit, with or without a space ("5 um", "5um"); the caller checks it.
  unit = std::string(trim(std::string_view(ptr, static_cast<std::size_t>(end - ptr))));
  return true;
}

std::string format_number(double v) {
  char buf[64];
  const auto [ptr, ec] = std::to_chars(buf, buf + sizeof buf, v);
  return ec == std::errc() ? std::string(buf, ptr) : std::string("?");
}

MapReader::MapReader(const YAML::Node& node, std::string path, Diagnostics& diag,
                     const YAML::Mark& where)
    : path_(std::move(path)), diag_(&diag), mark_(where) {
  if (!node.IsDefined() || node.IsNull()) return;
  mark_ = node.Mark();
  if (!node.IsMap()) {
    diag_->add(node.Mark(), (path_.empty() ? std::string("the config") : path_) +
                                " must be a mapping of keys to values, got " + node_kind(node));
    return;
  }
  present_ = true;
  for (auto it = node.begin(); it != node.end(); ++it) {
    const YAML::Node k = it->first;
    if (!k.IsScalar()) {
      diag_->add(k.Mark(), "keys in " + (path_.empty() ? std::string("the config") : path_) +
                               " must be plain names");
      continue;
    }
    if (const Entry* first = find(k.Scalar())) {
      diag_->add(k.Mark(), "duplicate key '" + k.Scalar() + "' in " +
                               (path_.empty() ? std::string("the config") : path_) +
                               " (first defined at line " +
                               std::to_string(first->key_node.Mark().line + 1) + ")");
      continue;
    }
    entries_.push_back(Entry{k.Scalar(), k, it->second, false});
  }
}

const MapReader::Entry* MapReader::find(std::string_view key) const {
  for (const Entry& e : entries_)
    if (e.key == key) return &e;
  return nullptr;
}

bool MapReader::has(std::string_view key) const { return find(key) != nullptr; }

void MapReader::note(std::string_view key) {
  for (const std::string& k : asked_)
    if (k == key) return;
  asked_.emplace_back(key);
}

YAML::Node MapReader::get(std::string_view key) {
  note(key);
  for (Entry& e : entries_)
    if (e.key == key) {
      e.used = true;
      return e.value;
    }
  return YAML::Node(YAML::NodeType::Undefined);
}

YAML::Mark MapReader::key_mark(std::string_view key) const {
  const Entry* e = find(key);
  return e ? e->key_node.Mark() : mark_;
}

std::string MapReader::key_path(std::string_view key) const {
  return path_.empty() ? std::string(key) : path_ + "." + std::string(key);
}

std::vector<std::string> MapReader::keys() const {
  std::vector<std::string> out;
  for (const Entry& e : entries_) out.push_back(e.key);
  return out;
}

YAML::Node MapReader::scalar(std::string_view key, Need need, const char* what) {
  note(key);
  if (!has(key)) {
    if (need == Need::required)
      diag_->add(mark_, "missing required key '" + key_path(key) + "' (" + what + ")");
    return YAML::Node(YAML::NodeType::Undefined);
  }
  YAML::Node v = get(key);
  if (v.IsNull()) {
    diag_->add(key_mark(key), key_path(key) + " has no value (expected " + what + ")");
    return YAML::Node(YAML::NodeType::Undefined);
  }
  if (!v.IsScalar()) {
    diag_->add(v.Mark(), key_path(key) + " must be " + what + ", got " + node_kind(v));
    return YAML::Node(YAML::NodeType::Undefined);
  }
  return v;
}

bool MapReader::number(std::string_view key, double& out, Range range, Need need) {
  const YAML::Node v = scalar(key, need, "a number");
  if (!v.IsDefined()) return false;
  double value = 0.0;
  std::string unit_text;
  if (!split_number(v.Scalar(), value, unit_text)) {
    diag_->add(v.Mark(), key_path(key) + " must be a number, got '" + v.Scalar() + "'");
    return false;
  }
  const std::optional<units::Unit> key_unit = units::unit_for_key(key);
  if (!unit_text.empty()) {
    const std::optional<units::Unit> written = units::parse_unit(unit_text);
    if (!written) {
      diag_->add(v.Mark(), key_path(key) + ": unknown unit '" + unit_text + "' in '" + v.Scalar() +
                               "'");
      return false;
    }
    const units::Dimension want = key_unit ? key_unit->dim : units::Dimension{};
    if (!(written->dim == want)) {
      diag_->add(v.Mark(), key_path(key) + ": '" + v.Scalar() + "' is " +
                               with_article(units::dimension_name(written->dim)) + ", but " +
                               std::string(key) + " is " +
                               with_article(units::dimension_name(want)) +
                               (key_unit ? " (" + key_unit->symbol + ")" : std::string()));
      return false;
    }
    value = value * written->to_si / (key_unit ? key_unit->to_si : 1.0);
  }
  if (!in_range(value, range)) {
    diag_->add(v.Mark(), key_path(key) + " must be " + range_text(range) +
                             (key_unit ? " " + key_unit->symbol : std::string()) + ", got " +
                             format_number(value));
    return false;
  }
  out = value;
  return true;
}

bool MapReader::integer(std::string_view key, std::int64_t& out, std::int64_t min,
                        std::int64_t max, Need need) {
  const YAML::Node v = scalar(key, need, "an integer");
  if (!v.IsDefined()) return false;
  const std::string_view text = trim(v.Scalar());
  std::int64_t value = 0;
  if (text.size() > 2 && text[0] == '0' && (text[1] == 'x' || text[1] == 'X')) {
    const auto [ptr, ec] = std::from_chars(text.data() + 2, text.data() + text.size(), value, 16);
    if (ec != std::errc() || ptr != text.data() + text.size()) {
      diag_->add(v.Mark(), key_path(key) + " must be an integer, got '" + v.Scalar() + "'");
      return false;
    }
  } else {
    // Decimal, possibly with exponent ("72e6") or a unit ("72 MHz"): read as a number first.
    double d = 0.0;
    std::string unit_text;
    if (!split_number(text, d, unit_text)) {
      diag_->add(v.Mark(), key_path(key) + " must be an integer, got '" + v.Scalar() + "'");
      return false;
    }
    if (!unit_text.empty()) {
      // Let number() do the unit work and its messages.
      if (!number(key, d, Range::any(), need)) return false;
    }
    if (d != std::floor(d) || std::fabs(d) > 9.0e15) {
      diag_->add(v.Mark(), key_path(key) + " must be an integer, got '" + v.Scalar() + "'");
      return false;
    }
    value = static_cast<std::int64_t>(d);
  }
  if (value < min || value > max) {
    diag_->add(v.Mark(), key_path(key) + " must be in [" + std::to_string(min) + ", " +
                             std::to_string(max) + "], got " + std::to_string(value));
    return false;
  }
  out = value;
  return true;
}

bool MapReader::boolean(std::string_view key, bool& out, Need need) {
  const YAML::Node v = scalar(key, need, "true or false");
  if (!v.IsDefined()) return false;
  const std::string& s = v.Scalar();
  if (s == "true" || s == "True" || s == "TRUE" || s == "yes" || s == "on") {
    out = true;
    return true;
  }
  if (s == "false" || s == "False" || s == "FALSE" || s == "no" || s == "off") {
    out = false;
    return true;
  }
  diag_->add(v.Mark(), key_path(key) + " must be true or false, got '" + s + "'");
  return false;
}

bool MapReader::string(std::string_view key, std::string& out, Need need) {
  const YAML::Node v = scalar(key, need, "a text value");
  if (!v.IsDefined()) return false;
  out = v.Scalar();
  return true;
}

bool MapReader::string_list(std::string_view key, std::vector<std::string>& out, Need need) {
  note(key);
  if (!has(key)) {
    if (need == Need::required)
      diag_->add(mark_, "missing required key '" + key_path(key) + "' (a list)");
    return false;
  }
  const YAML::Node v = get(key);
  if (v.IsScalar()) {  // a single name is a list of one
    out = {v.Scalar()};
    return true;
  }
  if (!v.IsSequence()) {
    diag_->add(v.IsNull() ? key_mark(key) : v.Mark(),
               key_path(key) + " must be a list, got " + node_kind(v));
    return false;
  }
  std::vector<std::string> items;
  bool ok = true;
  for (const YAML::Node& item : v) {
    if (!item.IsScalar()) {
      diag_->add(item.Mark(), key_path(key) + " items must be names, got " + node_kind(item));
      ok = false;
      continue;
    }
    items.push_back(item.Scalar());
  }
  if (ok) out = std::move(items);
  return ok;
}

MapReader MapReader::sub(std::string_view key, Need need) {
  note(key);
  if (!has(key) && need == Need::required)
    diag_->add(mark_, "missing required section '" + key_path(key) + "'");
  const YAML::Mark where = key_mark(key);
  return MapReader(get(key), key_path(key), *diag_, where);
}

void MapReader::report_bad_choice(std::string_view key, const std::string& got,
                                  const std::vector<std::string>& names) {
  std::string list;
  for (const std::string& n : names) list += (list.empty() ? "" : ", ") + n;
  std::string msg = key_path(key) + " must be one of " + list + ", got '" + got + "'";
  if (const std::string s = closest_match(got, names); !s.empty())
    msg += " (did you mean '" + s + "'?)";
  diag_->add(get(key).Mark(), msg);
}

void MapReader::finish() {
  for (const std::string& k : asked_) diag_->note_known_key(path_, k);
  for (const Entry& e : entries_) {
    if (e.used) continue;
    diag_->add_unknown_key(e.key_node.Mark(), path_, e.key, closest_match(e.key, asked_));
  }
}

}  // namespace feedloop::config
