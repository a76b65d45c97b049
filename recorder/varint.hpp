// Byte-level codecs of the flight-recorder log (docs/recorder.md, "Encoding"): LEB128 varints,
// zigzag for signed values, the XOR byte-mask code for doubles, and a bounds-checked reader.
// Header-only, no allocation on the decode side.
#pragma once

#include <bit>      // std::bit_cast
#include <cstdint>
#include <cstring>  // memcpy
#include <string>
#include <string_view>
#include <vector>

namespace feedloop::recorder {

inline uint64_t zigzag(int64_t v) { return (static_cast<uint64_t>(v) << 1) ^ static_cast<uint64_t>(v >> 63); }
inline int64_t unzigzag(uint64_t u) { return static_cast<int64_t>(u >> 1) ^ -static_cast<int64_t>(u & 1); }

// Appends to a byte buffer (the recorder thread's block; not used on the real-time side).
class ByteWriter {
 public:
  explicit ByteWriter(std::vector<uint8_t>& out) : out_(out) {}
  void u8(uint8_t v) { out_.push_back(v); }
  void u16le(uint16_t v) { for (int i = 0; i < 2; ++i) out_.push_back(static_cast<uint8_t>(v >> (8 * i))); }
  void u32le(uint32_t v) { for (int i = 0; i < 4; ++i) out_.push_back(static_cast<uint8_t>(v >> (8 * i))); }
  void varint(uint64_t v) {
    while (v >= 0x80) {
      out_.push_back(static_cast<uint8_t>(v | 0x80));
      v >>= 7;
    }
    out_.push_back(static_cast<uint8_t>(v));
  }
  void svarint(int64_t v) { varint(zigzag(v)); }
  // A double as (bits XOR bits of a prediction): one mask byte saying which of the 8 bytes of the
  // XOR are non-zero (bit i = byte i, little end first), then those bytes. A correct prediction
  // costs 1 byte, a value sharing sign/exponent/top mantissa bits with it 3-7, anything else 9.
  void f64x(double predicted, double v) {
    const uint64_t x = std::bit_cast<uint64_t>(v) ^ std::bit_cast<uint64_t>(predicted);
    uint8_t mask = 0;
    for (int i = 0; i < 8; ++i)
      if ((x >> (8 * i)) & 0xFF) mask = static_cast<uint8_t>(mask | (1u << i));
    out_.push_back(mask);
    for (int i = 0; i < 8; ++i)
      if (mask & (1u << i)) out_.push_back(static_cast<uint8_t>(x >> (8 * i)));
  }
  void f64raw(double v) {
    const uint64_t b = std::bit_cast<uint64_t>(v);
    for (int i = 0; i < 8; ++i) out_.push_back(static_cast<uint8_t>(b >> (8 * i)));
  }
  void str(std::string_view s) {
    varint(s.size());
    out_.insert(out_.end(), s.begin(), s.end());
  }

 private:
  std::vector<uint8_t>& out_;
};

// Reads from a byte span; every read checks bounds and sets failed() instead of reading past the
// end (the caller turns that into an error with the byte offset).
class ByteReader {
 public:
  ByteReader(const uint8_t* data, size_t size) : p_(data), n_(size) {}
  size_t pos() const { return i_; }
  size_t remaining() const { return n_ - i_; }
  bool failed() const { return failed_; }
  bool at_end() const { return i_ >= n_; }

  uint8_t u8() {
    if (!need(1)) return 0;
    return p_[i_++];
  }
  uint16_t u16le() {
    if (!need(2)) return 0;
    const uint16_t v = static_cast<uint16_t>(p_[i_] | (p_[i_ + 1] << 8));
    i_ += 2;
    return v;
  }
  uint32_t u32le() {
    if (!need(4)) return 0;
    uint32_t v = 0;
    for (int k = 0; k < 4; ++k) v |= static_cast<uint32_t>(p_[i_ + k]) << (8 * k);
    i_ += 4;
    return v;
  }
  uint64_t varint() {
    uint64_t v = 0;
    for (int shift = 0; shift < 64; shift += 7) {
      if (!need(1)) return 0;
      const uint8_t b = p_[i_++];
      v |= static_cast<uint64_t>(b & 0x7F) << shift;
      if (!(b & 0x80)) return v;
    }
    failed_ = true;  // more than 10 bytes: not a varint
    return 0;
  }
  int64_t svarint() { return unzigzag(varint()); }
  double f64x(double predicted) {
    const uint8_t mask = u8();
    uint64_t x = 0;
    for (int i = 0; i < 8; ++i)
      if (mask & (1u << i)) x |= static_cast<uint64_t>(u8()) << (8 * i);
    return std::bit_cast<double>(x ^ std::bit_cast<uint64_t>(predicted));
  }
  double f64raw() {
    if (!need(8)) return 0.0;
    uint64_t b = 0;
    for (int k = 0; k < 8; ++k) b |= static_cast<uint64_t>(p_[i_ + k]) << (8 * k);
    i_ += 8;
    return std::bit_cast<double>(b);
  }
  std::string str(size_t max_len) {
    const uint64_t len = varint();
    if (len > max_len || !need(static_cast<size_t>(len))) {
      failed_ = true;
      return {};
    }
    std::string s(reinterpret_cast<const char*>(p_ + i_), static_cast<size_t>(len));
    i_ += static_cast<size_t>(len);
    return s;
  }

 private:
  bool need(size_t k) {
    if (failed_ || n_ - i_ < k) {
      failed_ = true;
      return false;
    }
    return true;
  }
  const uint8_t* p_;
  size_t n_;
  size_t i_ = 0;
  bool failed_ = false;
};

}  // namespace feedloop::recorder
