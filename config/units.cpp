// Unit expressions and key-suffix units for config values (see units.hpp).
#include "config/units.hpp"

#include <cctype>   // isdigit
#include <cmath>    // pow
#include <numbers>  // pi
#include <utility>  // pair

namespace feedloop::config::units {
namespace {

constexpr double kPi = std::numbers::pi;

Dimension dim(int kg, int m, int s, int a = 0, int rad = 0, int byte = 0) {
  return Dimension{{kg, m, s, a, rad, byte}};
}

struct Atom {
  std::string_view symbol;
  Dimension dim;
  double to_si;
};

// Case-sensitive: "Nm" is a newton-metre, "nm" a nanometre, "MB" a megabyte.
const std::array<Atom, 42>& atoms() {
  static const std::array<Atom, 42> table = {{
      {"m", dim(0, 1, 0), 1.0},        {"cm", dim(0, 1, 0), 1e-2},
      {"mm", dim(0, 1, 0), 1e-3},      {"um", dim(0, 1, 0), 1e-6},
      {"µm", dim(0, 1, 0), 1e-6},      {"μm", dim(0, 1, 0), 1e-6},
      {"nm", dim(0, 1, 0), 1e-9},      {"in", dim(0, 1, 0), 0.0254},
      {"kg", dim(1, 0, 0), 1.0},       {"g", dim(1, 0, 0), 1e-3},
      {"s", dim(0, 0, 1), 1.0},        {"ms", dim(0, 0, 1), 1e-3},
      {"us", dim(0, 0, 1), 1e-6},      {"µs", dim(0, 0, 1), 1e-6},
      {"μs", dim(0, 0, 1), 1e-6},      {"ns", dim(0, 0, 1), 1e-9},
      {"min", dim(0, 0, 1), 60.0},     {"Hz", dim(0, 0, -1, 0, 1), 2 * kPi},
      {"kHz", dim(0, 0, -1, 0, 1), 2e3 * kPi},
      {"MHz", dim(0, 0, -1, 0, 1), 2e6 * kPi},
      {"rad", dim(0, 0, 0, 0, 1), 1.0},
      {"deg", dim(0, 0, 0, 0, 1), kPi / 180.0},
      {"°", dim(0, 0, 0, 0, 1), kPi / 180.0},
      {"N", dim(1, 1, -2), 1.0},       {"kN", dim(1, 1, -2), 1e3},
      {"mN", dim(1, 1, -2), 1e-3},     {"Nm", dim(1, 2, -2), 1.0},
      {"mNm", dim(1, 2, -2), 1e-3},    {"Ncm", dim(1, 2, -2), 1e-2},
      {"Ns", dim(1, 1, -1), 1.0},      {"A", dim(0, 0, 0, 1), 1.0},
      {"mA", dim(0, 0, 0, 1), 1e-3},   {"B", dim(0, 0, 0, 0, 0, 1), 1.0},
      {"kB", dim(0, 0, 0, 0, 0, 1), 1e3},
      {"MB", dim(0, 0, 0, 0, 0, 1), 1e6},
      {"GB", dim(0, 0, 0, 0, 0, 1), 1e9},
      {"KiB", dim(0, 0, 0, 0, 0, 1), 1024.0},
      {"MiB", dim(0, 0, 0, 0, 0, 1), 1048576.0},
      {"GiB", dim(0, 0, 0, 0, 0, 1), 1073741824.0},
      {"1", dim(0, 0, 0), 1.0},        {"steps", dim(0, 0, 0), 1.0},
      {"step", dim(0, 0, 0), 1.0},
  }};
  return table;
}

const Atom* find_atom(std::string_view s) {
  for (const Atom& a : atoms())
    if (a.symbol == s) return &a;
  return nullptr;
}

bool is_separator(char c) { return c == '*' || c == '/' || c == '-' || c == ' '; }

// One factor: an atom, optionally followed by an exponent "^n", "^-n", a digit ("s2") or the
// UTF-8 superscripts ² and ³.
bool parse_factor(std::string_view f, Dimension& d, double& scale, int sign) {
  int power = 1;
  std::string_view base = f;
  if (const auto caret = f.find('^'); caret != std::string_view::npos) {
    base = f.substr(0, caret);
    std::string_view e = f.substr(caret + 1);
    int esign = 1;
    if (!e.empty() && (e[0] == '-' || e[0] == '+')) {
      esign = e[0] == '-' ? -1 : 1;
      e.remove_prefix(1);
    }
    if (e.size() != 1 || !std::isdigit(static_cast<unsigned char>(e[0]))) return false;
    power = esign * (e[0] - '0');
  } else if (f.size() > 2 && f.substr(f.size() - 2) == "²") {
    base = f.substr(0, f.size() - 2), power = 2;
  } else if (f.size() > 2 && f.substr(f.size() - 2) == "³") {
    base = f.substr(0, f.size() - 2), power = 3;
  } else if (f.size() > 1 && std::isdigit(static_cast<unsigned char>(f.back())) && f != "1") {
    base = f.substr(0, f.size() - 1);
    power = f.back() - '0';
  }
  const Atom* atom = find_atom(base);
  if (atom == nullptr) return false;
  power *= sign;
  for (std::size_t i = 0; i < d.exp.size(); ++i) d.exp[i] += power * atom->dim.exp[i];
  scale *= std::pow(atom->to_si, power);
  return true;
}

}  // namespace

std::optional<Unit> parse_unit(std::string_view text) {
  while (!text.empty() && text.front() == ' ') text.remove_prefix(1);
  while (!text.empty() && text.back() == ' ') text.remove_suffix(1);
  if (text.empty()) return std::nullopt;
  Unit unit;
  unit.symbol = std::string(text);
  int sign = 1;  // +1 numerator, -1 after the first '/'
  std::size_t i = 0;
  while (i < text.size()) {
    std::size_t j = i;
    // A factor runs to the next separator; a '-' right after '^' belongs to the exponent.
    while (j < text.size() && !(is_separator(text[j]) && !(text[j] == '-' && j > 0 && text[j - 1] == '^')))
      ++j;
    const std::string_view factor = text.substr(i, j - i);
    if (factor.empty()) return std::nullopt;
    if (!parse_factor(factor, unit.dim, unit.to_si, sign)) return std::nullopt;
    if (j == text.size()) break;
    if (text[j] == '/') {
      if (sign < 0) return std::nullopt;  // "a/b/c" is ambiguous: reject
      sign = -1;
    }
    i = j + 1;
    if (i == text.size()) return std::nullopt;  // trailing separator
  }
  return unit;
}

std::optional<Unit> unit_for_key(std::string_view key) {
  // Suffix -> unit expression. Checked longest first.
  static const std::array<std::pair<std::string_view, std::string_view>, 24> suffixes = {{
      {"_nm_per_a", "Nm/A"},  {"_nm_s", "Nm*s"},
      {"_ns_per_m", "N*s/m"}, {"_n_per_m", "N/m"},  {"_per_mm", "1/mm"},   {"_per_s2", "1/s^2"},
      {"_kg_m2", "kg*m^2"},   {"_mm_s3", "mm/s^3"}, {"_mm_s2", "mm/s^2"},  {"_per_s", "1/s"},
      {"_mm_s", "mm/s"},      {"_deg", "deg"},      {"_hz", "Hz"},         {"_mm", "mm"},
      {"_um", "um"},          {"_kg", "kg"},        {"_nm", "Nm"},         {"_ms", "ms"},
      {"_us", "us"},          {"_mb", "MB"},        {"_n", "N"},           {"_a", "A"},
      {"_s", "s"},            {"_m", "m"},
  }};
  const std::pair<std::string_view, std::string_view>* best = nullptr;
  for (const auto& s : suffixes) {
    if (key.size() > s.first.size() && key.substr(key.size() - s.first.size()) == s.first &&
        (best == nullptr || s.first.size() > best->first.size()))
      best = &s;
  }
  if (best == nullptr) return std::nullopt;
  return parse_unit(best->second);
}

std::string dimension_name(const Dimension& d) {
  static const std::array<std::pair<Dimension, std::string_view>, 19> names = {{
      {dim(0, 0, 0), "dimensionless number"},
      {dim(0, 1, 0), "length"},
      {dim(0, 1, -1), "velocity"},
      {dim(0, 1, -2), "acceleration"},
      {dim(0, 1, -3), "jerk"},
      {dim(0, 0, 1), "time"},
      {dim(0, 0, -1), "rate (1/s)"},
      {dim(0, 0, -2), "rate squared (1/s^2)"},
      {dim(0, 0, -1, 0, 1), "frequency"},
      {dim(1, 0, 0), "mass"},
      {dim(1, 1, -2), "force"},
      {dim(1, 0, -2), "stiffness"},
      {dim(1, 0, -1), "damping"},
      {dim(1, 2, -2), "torque"},
      {dim(1, 2, 0), "moment of inertia"},
      {dim(0, 0, 0, 0, 1), "angle"},
      {dim(0, 0, 0, 1), "current"},
      {dim(0, 0, 0, 0, 0, 1), "data size"},
      {dim(0, -1, 0), "inverse length"},
  }};
  for (const auto& [dd, name] : names)
    if (dd == d) return std::string(name);
  static const std::array<std::string_view, 6> base = {"kg", "m", "s", "A", "rad", "B"};
  std::string out;
  for (std::size_t i = 0; i < d.exp.size(); ++i) {
    if (d.exp[i] == 0) continue;
    if (!out.empty()) out += "*";
    out += base[i];
    if (d.exp[i] != 1) out += "^" + std::to_string(d.exp[i]);
  }
  return "quantity in " + out;
}

}  // namespace feedloop::config::units
