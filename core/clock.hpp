// Time for everything that runs in the servo thread (DESIGN.md, "Threads and time").
// The daemon uses MonotonicClock; tests, batch mode and replay use VirtualClock and run the
// same pipeline deterministically and faster than real time. There is one pipeline.
#pragma once

#include <atomic>
#include <cstdint>

namespace feedloop {

class Clock {
 public:
  virtual ~Clock() = default;
  // Nanoseconds on this clock's own time line (monotonic, arbitrary epoch).
  virtual int64_t now_ns() const = 0;
  // Blocks (or, in virtual time, advances) until now_ns() >= deadline_ns.
  // Real-time safe: no allocation, no locks.
  virtual void sleep_until_ns(int64_t deadline_ns) = 0;
  // True if time only moves when sleep_until_ns is called.
  virtual bool is_virtual() const = 0;
};

// CLOCK_MONOTONIC with absolute-deadline clock_nanosleep (TIMER_ABSTIME).
class MonotonicClock final : public Clock {
 public:
  int64_t now_ns() const override;
  void sleep_until_ns(int64_t deadline_ns) override;
  bool is_virtual() const override { return false; }
};

// Time that advances only when someone sleeps: deterministic, as fast as the CPU allows.
class VirtualClock final : public Clock {
 public:
  explicit VirtualClock(int64_t start_ns = 0) : now_ns_(start_ns) {}
  int64_t now_ns() const override { return now_ns_.load(std::memory_order_acquire); }
  void sleep_until_ns(int64_t deadline_ns) override {
    if (deadline_ns > now_ns_.load(std::memory_order_relaxed))
      now_ns_.store(deadline_ns, std::memory_order_release);
  }
  bool is_virtual() const override { return true; }
  void advance_ns(int64_t dt_ns) { now_ns_.fetch_add(dt_ns, std::memory_order_acq_rel); }

 private:
  std::atomic<int64_t> now_ns_;
};

inline constexpr int64_t kNsPerS = 1'000'000'000;
inline constexpr double seconds_from_ns(int64_t ns) { return static_cast<double>(ns) * 1e-9; }
inline constexpr int64_t ns_from_seconds(double s) { return static_cast<int64_t>(s * 1e9 + (s >= 0 ? 0.5 : -0.5)); }

}  // namespace feedloop
