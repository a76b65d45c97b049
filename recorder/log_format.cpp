// File header encoding and decoding (docs/recorder.md, "File header").
#include "recorder/log_format.hpp"

#include <cstring>  // memcmp
#include <string>

#include "recorder/block_codec.hpp"  // crc32
#include "recorder/varint.hpp"

namespace feedloop::recorder {

void encode_header(const LogHeader& h, std::vector<uint8_t>& out) {
  std::vector<uint8_t> body;
  ByteWriter b(body);
  b.str(h.print_name);
  b.varint(h.part);
  b.svarint(h.start_unix_ns);
  b.svarint(h.start_host_ns);
  b.varint(h.joints.size());
  for (const JointInfo& j : h.joints) {
    b.str(j.name);
    b.f64raw(j.steps_per_mm);
    b.f64raw(j.encoder_resolution_mm);
    b.svarint(j.clock_hz);
  }
  b.str(h.config_yaml);

  ByteWriter w(out);
  out.insert(out.end(), kMagic, kMagic + sizeof kMagic);
  w.u16le(kFormatVersion);
  w.u16le(0);  // flags, none defined
  w.u32le(static_cast<uint32_t>(body.size()));
  out.insert(out.end(), body.begin(), body.end());
  w.u32le(crc32(body.data(), body.size()));
}

Result<uint32_t> parse_fixed_header(const uint8_t* data, size_t size) {
  if (size < kFixedHeaderBytes)
    return Error{"truncated file header at byte offset " + std::to_string(size) + " (a log starts with " +
                     std::to_string(kFixedHeaderBytes) + " header bytes)", {}};
  if (std::memcmp(data, kMagic, sizeof kMagic) != 0)
    return Error{"not a feedloop log: bad magic at byte offset 0 (expected \"FLOOPREC\")", {}};
  ByteReader r(data + 8, size - 8);
  const uint16_t version = r.u16le();
  r.u16le();
  const uint32_t body = r.u32le();
  if (version == 0 || version > kFormatVersion)
    return Error{"unsupported log format version " + std::to_string(version) + " at byte offset 8 (this build reads 1.." +
                     std::to_string(kFormatVersion) + ")", {}};
  if (body > kMaxHeaderBody)
    return Error{"implausible header length " + std::to_string(body) + " at byte offset 12", {}};
  return body;
}

Result<LogHeader> parse_header_body(const uint8_t* data, size_t size_with_crc, uint16_t version) {
  if (size_with_crc < 4) return Error{"truncated file header", {}};
  const size_t n = size_with_crc - 4;
  ByteReader c(data + n, 4);
  if (c.u32le() != crc32(data, n))
    return Error{"file header CRC mismatch (header bytes " + std::to_string(kFixedHeaderBytes) + ".." +
                     std::to_string(kFixedHeaderBytes + n) + " are damaged)", {}};
  LogHeader h;
  h.version = version;
  ByteReader r(data, n);
  h.print_name = r.str(4096);
  h.part = static_cast<uint32_t>(r.varint());
  h.start_unix_ns = r.svarint();
  h.start_host_ns = r.svarint();
  const uint64_t joints = r.varint();
  if (joints > static_cast<uint64_t>(kMaxJoints))
    return Error{"file header lists " + std::to_string(joints) + " joints (at most " + std::to_string(kMaxJoints) + ")", {}};
  for (uint64_t i = 0; i < joints; ++i) {
    JointInfo j;
    j.name = r.str(256);
    j.steps_per_mm = r.f64raw();
    j.encoder_resolution_mm = r.f64raw();
    j.clock_hz = r.svarint();
    h.joints.push_back(j);
  }
  h.config_yaml = r.str(kMaxHeaderBody);
  if (r.failed()) return Error{"malformed file header body at byte offset " + std::to_string(kFixedHeaderBytes + r.pos()), {}};
  return h;
}

}  // namespace feedloop::recorder
