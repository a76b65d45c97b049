// LEB128 variable-length integers and zigzag signed mapping for the wire protocol
// (docs/protocol.md, "Integers"). Header-only, no allocation: usable on the device.
#pragma once

#include <cstddef>
#include <cstdint>

namespace feedloop::protocol {

inline uint64_t zigzag(int64_t v) { return (static_cast<uint64_t>(v) << 1) ^ static_cast<uint64_t>(v >> 63); }
inline int64_t unzigzag(uint64_t u) { return static_cast<int64_t>(u >> 1) ^ -static_cast<int64_t>(u & 1); }

// Writes v at out[pos..]; returns the new pos, or 0 when it does not fit in cap.
inline size_t put_varint(uint8_t* out, size_t pos, size_t cap, uint64_t v) {
  do {
    if (pos >= cap) return 0;
    uint8_t b = v & 0x7F;
    v >>= 7;
    out[pos++] = b | (v ? 0x80 : 0);
  } while (v);
  return pos;
}

inline size_t varint_size(uint64_t v) {
  size_t n = 1;
  while (v >>= 7) ++n;
  return n;
}

// Reads a varint from in[pos..len); returns false on truncation or overlong input.
inline bool get_varint(const uint8_t* in, size_t len, size_t& pos, uint64_t& v) {
  v = 0;
  for (int shift = 0; shift < 64; shift += 7) {
    if (pos >= len) return false;
    const uint8_t b = in[pos++];
    v |= static_cast<uint64_t>(b & 0x7F) << shift;
    if (!(b & 0x80)) return true;
  }
  return false;
}

// Little-endian fixed-width helpers.
inline size_t put_u16(uint8_t* out, size_t pos, size_t cap, uint16_t v) {
  if (pos + 2 > cap) return 0;
  out[pos] = v & 0xFF;
  out[pos + 1] = v >> 8;
  return pos + 2;
}

}  // namespace feedloop::protocol
