// Reading a fuzz input as a little program of operations: the harnesses take an operation byte,
// then its arguments, until the input runs out (reads past the end give zeros). Seeds can be
// written by hand (fuzz/README.md lists each target's operations).
#pragma once

#include <cstddef>
#include <cstdint>

namespace feedloop::fuzz {

// A failed invariant is a finding: trap (libFuzzer saves the input).
inline void check(bool ok) {
  if (!ok) __builtin_trap();
}

class FuzzInput {
 public:
  FuzzInput(const uint8_t* data, size_t size) : data_(data), size_(size) {}
  bool empty() const { return pos_ >= size_; }
  uint8_t u8() { return pos_ < size_ ? data_[pos_++] : 0; }
  uint16_t u16() {
    const uint16_t lo = u8();
    return static_cast<uint16_t>(lo | (u8() << 8));
  }
  uint32_t u32() {
    const uint32_t lo = u16();
    return lo | (static_cast<uint32_t>(u16()) << 16);
  }
  uint64_t u64() {
    const uint64_t lo = u32();
    return lo | (static_cast<uint64_t>(u32()) << 32);
  }
  // Up to n bytes (fewer at the end of the input); `got` says how many.
  const uint8_t* take(size_t n, size_t& got) {
    const size_t left = size_ - pos_;
    got = n < left ? n : left;
    const uint8_t* p = data_ + pos_;
    pos_ += got;
    return p;
  }

 private:
  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
};

}  // namespace feedloop::fuzz
