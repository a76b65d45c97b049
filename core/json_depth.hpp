// How deeply a JSON text nests its arrays and objects, counted without parsing it.
//
// nlohmann::json parses any depth (its parser keeps an explicit stack) but dumps, compares and
// copies values by recursion: a client's 100 000 nested brackets (200 kB, inside every body
// limit) parsed fine and then overflowed the stack when the value was stored or echoed. Every
// JSON a client sends is measured with this first and refused beyond kMaxClientJsonDepth.
#pragma once

#include <cstddef>
#include <string_view>

namespace feedloop {

// Deeper than any request a front end sends (Mainsail's stored UI settings nest under 10).
inline constexpr std::size_t kMaxClientJsonDepth = 64;

// The greatest nesting of [ and { outside strings (escapes inside strings honoured). Stops
// counting past `limit` and returns limit + 1: the text's length does not matter beyond that.
inline std::size_t json_nesting_depth(std::string_view text, std::size_t limit = kMaxClientJsonDepth) {
  std::size_t depth = 0, deepest = 0;
  bool in_string = false, escaped = false;
  for (const char c : text) {
    if (in_string) {
      if (escaped)
        escaped = false;
      else if (c == '\\')
        escaped = true;
      else if (c == '"')
        in_string = false;
      continue;
    }
    if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > deepest) deepest = depth;
      if (deepest > limit) return limit + 1;
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    }
  }
  return deepest;
}

}  // namespace feedloop
