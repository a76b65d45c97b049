// The boundary for outside strings: text that enters from a client, a file or a device (G-code
// free text such as M117/M118 messages and file names, JSON strings, device error text) is made
// valid UTF-8 once, where it enters, so every later consumer (the status JSON, the log, the
// recording) can rely on it. Invalid bytes become U+FFFD, as WHATWG's decoder and Python's
// errors="replace" do: one replacement per maximal invalid subpart (Unicode 15, Sect. 3.9, U+FFFD
// substitution of maximal subparts).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace feedloop {

// Length of the valid UTF-8 sequence that starts at s[i], or 0 when none does. On 0,
// *invalid_len is the length of the maximal invalid subpart to replace with one U+FFFD (>= 1).
inline size_t utf8_sequence_length(std::string_view s, size_t i, size_t* invalid_len) {
  const auto b = [&](size_t k) { return static_cast<uint8_t>(s[k]); };
  const uint8_t c = b(i);
  *invalid_len = 1;
  if (c < 0x80) return 1;
  size_t need;
  uint8_t lo = 0x80, hi = 0xBF;  // bounds of the second byte (Unicode Table 3-7)
  if (c >= 0xC2 && c <= 0xDF) {
    need = 1;
  } else if (c >= 0xE0 && c <= 0xEF) {
    need = 2;
    if (c == 0xE0) lo = 0xA0;  // no overlong forms
    if (c == 0xED) hi = 0x9F;  // no surrogates
  } else if (c >= 0xF0 && c <= 0xF4) {
    need = 3;
    if (c == 0xF0) lo = 0x90;  // no overlong forms
    if (c == 0xF4) hi = 0x8F;  // nothing above U+10FFFF
  } else {
    return 0;  // a continuation byte, C0/C1 (overlong) or F5..FF: invalid on its own
  }
  size_t k = 1;
  for (; k <= need; ++k) {
    if (i + k >= s.size()) break;
    const uint8_t x = b(i + k);
    if (k == 1 ? (x < lo || x > hi) : (x < 0x80 || x > 0xBF)) break;
  }
  if (k > need) return need + 1;
  *invalid_len = k;  // the lead byte and the continuation bytes that were still plausible
  return 0;
}

inline bool is_valid_utf8(std::string_view s) {
  size_t bad = 0;
  for (size_t i = 0; i < s.size();) {
    const size_t n = utf8_sequence_length(s, i, &bad);
    if (n == 0) return false;
    i += n;
  }
  return true;
}

// `s` with every invalid subpart replaced by U+FFFD, appended to `out` (cleared first). Reuses
// `out`'s storage: no allocation when it is large enough, so the G-code parser can call it per
// line.
inline void assign_valid_utf8(std::string& out, std::string_view s) {
  out.clear();
  size_t bad = 0;
  size_t run = 0;  // start of the current run of valid bytes
  for (size_t i = 0; i < s.size();) {
    const size_t n = utf8_sequence_length(s, i, &bad);
    if (n != 0) {
      i += n;
      continue;
    }
    out.append(s.substr(run, i - run));
    out.append("\xEF\xBF\xBD");
    i += bad;
    run = i;
  }
  out.append(s.substr(run));
}

inline std::string valid_utf8(std::string_view s) {
  std::string out;
  assign_valid_utf8(out, s);
  return out;
}

}  // namespace feedloop
