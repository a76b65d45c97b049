// A single-writer seqlock: the real-time writer never blocks; readers copy and retry if a write
// overlapped (the LinuxCNC head/tail idea, with std::atomic fences as it should have had).
// T must be trivially copyable. Used by the engine (status, link telemetry) and the drivers (clock
// estimates published by an I/O thread).
#pragma once

#include <atomic>
#include <cstdint>
#include <cstring>
#include <type_traits>

namespace feedloop {

template <class T>
class Seqlock {
  static_assert(std::is_trivially_copyable_v<T>);

 public:
  // Writer side (one thread). Real-time safe.
  void store(const T& v) {
    const uint64_t s = seq_.load(std::memory_order_relaxed);
    seq_.store(s + 1, std::memory_order_relaxed);
    std::atomic_thread_fence(std::memory_order_release);
    std::memcpy(&data_, &v, sizeof(T));
    std::atomic_thread_fence(std::memory_order_release);
    seq_.store(s + 2, std::memory_order_release);
  }

  // Reader side (any thread).
  T load() const {
    T out;
    for (;;) {
      const uint64_t s0 = seq_.load(std::memory_order_acquire);
      if (s0 & 1u) continue;
      std::memcpy(&out, &data_, sizeof(T));
      std::atomic_thread_fence(std::memory_order_acquire);
      if (seq_.load(std::memory_order_relaxed) == s0) return out;
    }
  }

 private:
  std::atomic<uint64_t> seq_{0};
  T data_{};
};

}  // namespace feedloop
