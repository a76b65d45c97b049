// The file header of a flight-recorder log (docs/recorder.md, "File header"): magic, format
// version, and a CRC-checked body with the print name, rotation part, start times, joints and the
// config text.
#pragma once

#include <cstdint>
#include <vector>

#include "core/result.hpp"
#include "recorder/records.hpp"

namespace feedloop::recorder {

inline constexpr char kMagic[8] = {'F', 'L', 'O', 'O', 'P', 'R', 'E', 'C'};
inline constexpr size_t kFixedHeaderBytes = 16;  // magic, u16 version, u16 flags, u32 body length
inline constexpr uint32_t kMaxHeaderBody = 16u << 20;
inline constexpr const char* kLogExtension = ".flrec";

// Appends the whole header (fixed part, body, CRC) to `out`.
void encode_header(const LogHeader& h, std::vector<uint8_t>& out);

// From the first kFixedHeaderBytes: the body length (Error: not a log, or a newer version).
Result<uint32_t> parse_fixed_header(const uint8_t* data, size_t size);

// Body + its CRC (4 bytes after the body) -> header. `version` comes from the fixed part.
Result<LogHeader> parse_header_body(const uint8_t* data, size_t size_with_crc, uint16_t version);

}  // namespace feedloop::recorder
