// CRC16-CCITT (polynomial 0x1021, initial value 0xFFFF, no reflection, no final xor) over the
// frame bytes after the sync byte (docs/protocol.md, "Frames"). Header-only, no allocation.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace feedloop::protocol {

namespace detail {
constexpr std::array<uint16_t, 256> make_crc16_table() {
  std::array<uint16_t, 256> t{};
  for (int i = 0; i < 256; ++i) {
    uint16_t c = static_cast<uint16_t>(i << 8);
    for (int b = 0; b < 8; ++b) c = (c & 0x8000) ? static_cast<uint16_t>((c << 1) ^ 0x1021) : static_cast<uint16_t>(c << 1);
    t[static_cast<size_t>(i)] = c;
  }
  return t;
}
inline constexpr std::array<uint16_t, 256> kCrc16Table = make_crc16_table();
}  // namespace detail

inline uint16_t crc16_ccitt(const uint8_t* data, size_t n, uint16_t crc = 0xFFFF) {
  for (size_t i = 0; i < n; ++i)
    crc = static_cast<uint16_t>((crc << 8) ^ detail::kCrc16Table[((crc >> 8) ^ data[i]) & 0xFF]);
  return crc;
}

}  // namespace feedloop::protocol
