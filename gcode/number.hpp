// Scanning of G-code numbers ("-.8", "+5", "12.", "1e-05") from a line, without allocation.
// Fast path: up to 18 significant digits and at most 22 fractional digits give the correctly
// rounded double as mantissa / 10^k (both exact in a double: Clinger's fast path); anything
// longer, or with an exponent, goes to std::from_chars (also correctly rounded).
#pragma once

#include <charconv>
#include <cstddef>
#include <cstdint>
#include <string_view>

namespace feedloop::gcode {

struct NumberScan {
  enum class Status : uint8_t { kOk, kNoDigits, kOutOfRange };
  Status status = Status::kNoDigits;
  double value = 0.0;
  size_t end = 0;  // index one past the last character consumed
};

inline bool is_digit(char c) { return c >= '0' && c <= '9'; }

// Scans a number starting at s[pos] (sign allowed). With allow_exponent, a lowercase 'e' followed
// by an explicit sign and a digit continues the number as an exponent (see gcode/parser.hpp).
inline NumberScan scan_number(std::string_view s, size_t pos, bool allow_exponent) {
  static constexpr double kPow10[] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
                                      1e8,  1e9,  1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
                                      1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
  constexpr uint64_t kMaxExactMantissa = uint64_t{1} << 53;
  NumberScan r;
  const size_t n = s.size();
  size_t i = pos;
  bool negative = false;
  if (i < n && (s[i] == '+' || s[i] == '-')) {
    negative = s[i] == '-';
    ++i;
  }
  const size_t mantissa_start = i;
  uint64_t mantissa = 0;
  int significant = 0;  // digits accumulated into `mantissa` after the first non-zero one
  int fraction = 0;     // digits after the '.' accumulated into `mantissa`
  bool any_digit = false;
  bool exact = true;
  bool in_fraction = false;
  for (; i < n; ++i) {
    const char c = s[i];
    if (is_digit(c)) {
      any_digit = true;
      if (significant < 18) {
        mantissa = mantissa * 10 + static_cast<uint64_t>(c - '0');
        if (mantissa != 0) ++significant;
        if (in_fraction) ++fraction;
      } else {
        exact = false;  // too many digits for the fast path
      }
    } else if (c == '.' && !in_fraction) {
      in_fraction = true;
    } else {
      break;
    }
  }
  if (!any_digit) {
    r.end = i;
    return r;
  }
  if (allow_exponent && i + 2 < n && s[i] == 'e' && (s[i + 1] == '+' || s[i + 1] == '-') &&
      is_digit(s[i + 2])) {
    i += 2;
    while (i < n && is_digit(s[i])) ++i;
    exact = false;
  }
  r.end = i;
  if (exact && mantissa <= kMaxExactMantissa && fraction <= 22) {
    const double m = static_cast<double>(mantissa);
    const double v = fraction == 0 ? m : m / kPow10[fraction];
    r.value = negative ? -v : v;
    r.status = NumberScan::Status::kOk;
    return r;
  }
  double v = 0.0;
  const auto res = std::from_chars(s.data() + mantissa_start, s.data() + i, v);
  if (res.ec == std::errc::result_out_of_range) {
    r.status = NumberScan::Status::kOutOfRange;
    return r;
  }
  if (res.ec != std::errc() || res.ptr != s.data() + i) {
    r.status = NumberScan::Status::kNoDigits;  // cannot happen for the characters scanned above
    return r;
  }
  r.value = negative ? -v : v;
  r.status = NumberScan::Status::kOk;
  return r;
}

}  // namespace feedloop::gcode
