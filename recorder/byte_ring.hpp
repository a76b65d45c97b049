// Lock-free single-producer single-consumer ring of variable-length records (the real-time side
// of the flight recorder). Storage is allocated once, at construction; try_push never allocates,
// never blocks and never waits: when the record does not fit it returns false (the caller counts a
// drop). Layout: every entry starts at an 8-byte boundary with an 8-byte header {u32 length,
// u8 type, 3 unused}, then the payload padded to 8; an entry that would cross the end of the
// buffer is preceded by a wrap marker (type 0xFF) filling the rest, and starts at 0.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstring>  // memcpy
#include <memory>

namespace feedloop::recorder {

class ByteRing {
 public:
  static constexpr uint8_t kWrap = 0xFF;

  // capacity_bytes is rounded up to a power of two (at least 256).
  explicit ByteRing(size_t capacity_bytes) {
    size_t c = 256;
    while (c < capacity_bytes) c <<= 1;
    cap_ = c;
    buf_ = std::make_unique<uint64_t[]>(c / 8);  // 8-aligned storage
  }
  ByteRing(const ByteRing&) = delete;
  ByteRing& operator=(const ByteRing&) = delete;

  size_t capacity() const { return cap_; }
  // Largest payload that can ever be pushed (a quarter of the ring, so one big record cannot
  // starve the others).
  size_t max_payload() const { return cap_ / 4 - kHeader; }

  // Producer side. Copies a then b (b may be null) as one record. False (nothing written) when full.
  bool try_push(uint8_t type, const void* a, size_t na, const void* b = nullptr, size_t nb = 0) {
    const size_t len = na + nb;
    if (len > max_payload()) return false;
    const size_t entry = kHeader + round8(len);
    uint64_t head = head_.load(std::memory_order_relaxed);
    const size_t pos = static_cast<size_t>(head & (cap_ - 1));
    const size_t to_end = cap_ - pos;
    const size_t need = entry <= to_end ? entry : to_end + entry;
    if (need > cap_ - static_cast<size_t>(head - tail_cache_)) {
      tail_cache_ = tail_.load(std::memory_order_acquire);
      if (need > cap_ - static_cast<size_t>(head - tail_cache_)) return false;
    }
    uint8_t* base = bytes();
    size_t at = pos;
    if (entry > to_end) {
      write_header(base + pos, 0, kWrap);
      head += to_end;
      at = 0;
    }
    write_header(base + at, static_cast<uint32_t>(len), type);
    if (na) std::memcpy(base + at + kHeader, a, na);
    if (nb) std::memcpy(base + at + kHeader + na, b, nb);
    head_.store(head + entry, std::memory_order_release);
    return true;
  }

  // Consumer side: calls f(type, payload, length) for every record present, oldest first, and
  // frees each after f returns. Returns the number of records.
  template <class F>
  size_t drain(F&& f) {
    uint64_t tail = tail_.load(std::memory_order_relaxed);
    const uint64_t head = head_.load(std::memory_order_acquire);
    size_t n = 0;
    const uint8_t* base = bytes();
    while (tail != head) {
      const size_t pos = static_cast<size_t>(tail & (cap_ - 1));
      uint32_t len = 0;
      std::memcpy(&len, base + pos, 4);
      const uint8_t type = base[pos + 4];
      if (type == kWrap) {
        tail += cap_ - pos;
      } else {
        f(type, base + pos + kHeader, static_cast<size_t>(len));
        tail += kHeader + round8(len);
        ++n;
      }
      tail_.store(tail, std::memory_order_release);
    }
    return n;
  }

  // Bytes in use (approximate from either side).
  size_t used() const {
    return static_cast<size_t>(head_.load(std::memory_order_acquire) - tail_.load(std::memory_order_acquire));
  }

 private:
  static constexpr size_t kHeader = 8;
  static size_t round8(size_t n) { return (n + 7) & ~size_t{7}; }
  uint8_t* bytes() { return reinterpret_cast<uint8_t*>(buf_.get()); }
  static void write_header(uint8_t* p, uint32_t len, uint8_t type) {
    std::memcpy(p, &len, 4);
    p[4] = type;
    p[5] = p[6] = p[7] = 0;
  }

  static constexpr size_t kCacheLine = 64;
  alignas(kCacheLine) std::atomic<uint64_t> head_{0};  // written by the producer
  uint64_t tail_cache_ = 0;                            // producer's last view of tail_
  alignas(kCacheLine) std::atomic<uint64_t> tail_{0};  // written by the consumer
  alignas(kCacheLine) std::unique_ptr<uint64_t[]> buf_;
  size_t cap_ = 0;
};

}  // namespace feedloop::recorder
