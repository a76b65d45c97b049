// External plant v1 (DESIGN.md) from the plant's side: the handshake line and the per-period
// lines feedloop writes, parsed into values or a clear error; the answer line formatted.
//
//   feedloop -> plant:  "feedloop-plant 1 axes=x,y period_s=0.0001"   then "t_s u_1 ... u_n"
//   plant -> feedloop:  "ready"                                       then "y_1 ... y_n"
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "core/result.hpp"

namespace feedloop::plant2 {

struct Handshake {
  std::vector<std::string> axes;  // x, y, z, e, or A, B, C
  double period_s = 0.0;
};

// Errors: not "feedloop-plant 1 axes=<a>[,<b>...] period_s=<positive number>".
Result<Handshake> parse_handshake(std::string_view line);

// Parses "t_s u_1 ... u_n" (exactly n + 1 finite decimal numbers) into t_s and u[0..n).
// Returns an empty string on success, else what is wrong (quoting the line). No allocation on
// success.
std::string parse_period_line(std::string_view line, size_t n, double* t_s, double* u);

// "y_1 ... y_n\n" with 12 significant digits into out (cleared first).
void format_answer(const double* y, size_t n, std::string* out);

}  // namespace feedloop::plant2
