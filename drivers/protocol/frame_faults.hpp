// A one-way frame line with fault injection (docs/protocol.md, "Transports"), used by the mock
// transport (virtual time, with link latency) and by feedloop-vmcu on its pseudo-terminal (real
// time, no added latency). Each frame sent is, with the configured probabilities: dropped, has one
// byte corrupted, is sent twice, is reordered (held reorder_extra_s so that later frames overtake
// it) or delayed (held delay_extra_s, beyond the retransmit timeout). Without reorder/delay the
// line is FIFO: latency jitter alone never reorders frames.
//
// Fixed capacity, no heap: frames wait in a pool of kCapacity slots ordered by due time (a binary
// heap of slot indices; FIFO among equal times). A frame that finds the pool full is lost and
// counted in `overflowed` (the reliable link retransmits it). Owner: one thread.
#pragma once

#include <algorithm>  // std::push_heap, std::pop_heap, std::max
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>  // memcpy
#include <random>

#include "drivers/protocol/frame.hpp"

namespace feedloop::protocol {

struct FrameFaults {
  double drop = 0.0;       // probability per frame
  double corrupt = 0.0;
  double duplicate = 0.0;
  double reorder = 0.0;
  double delay = 0.0;
  double latency_s = 0.0;        // one way
  double jitter_s = 0.0;         // uniform extra one-way latency in [0, jitter_s]
  double reorder_extra_s = 2e-3;
  double delay_extra_s = 80e-3;
};

struct FrameFaultStats {
  uint64_t frames = 0, dropped = 0, corrupted = 0, duplicated = 0, reordered = 0, delayed = 0, overflowed = 0;
};

template <int kCapacity>
class FaultyFrameLine {
 public:
  FaultyFrameLine() { clear(); }
  FaultyFrameLine(const FaultyFrameLine&) = delete;
  FaultyFrameLine& operator=(const FaultyFrameLine&) = delete;

  void configure(const FrameFaults& f, uint64_t seed) {
    faults_ = f;
    rng_.seed(seed);
    clear();
  }
  void set_faults(const FrameFaults& f) { faults_ = f; }

  // Applies the faults to one frame sent at t_s and schedules it (and its duplicate).
  void send(const uint8_t* data, size_t n, double t_s) {
    if (n > kMaxFrame) return;
    ++stats_.frames;
    if (u() < faults_.drop) {
      ++stats_.dropped;
      return;
    }
    const bool corrupt = u() < faults_.corrupt && n > 0;
    const size_t corrupt_at = corrupt ? static_cast<size_t>(u() * static_cast<double>(n)) % n : 0;
    const auto corrupt_xor = static_cast<uint8_t>(1 + (rng_() % 255));
    if (corrupt) ++stats_.corrupted;
    double t = std::max(t_s + faults_.latency_s + faults_.jitter_s * u(), fifo_t_);
    fifo_t_ = t;
    if (u() < faults_.reorder) {
      t += faults_.reorder_extra_s;
      ++stats_.reordered;
    }
    if (u() < faults_.delay) {
      t += faults_.delay_extra_s;
      ++stats_.delayed;
    }
    if (u() < faults_.duplicate) {
      if (schedule(data, n, t + 0.5 * faults_.latency_s + faults_.jitter_s * u(), corrupt, corrupt_at, corrupt_xor))
        ++stats_.duplicated;
    }
    schedule(data, n, t, corrupt, corrupt_at, corrupt_xor);
  }

  // The earliest frame due at or before t_s: copied to out (kMaxFrame bytes), its size in n.
  bool pop_due(double t_s, uint8_t* out, size_t& n) {
    if (heap_len_ == 0 || slots_[heap_[0]].t > t_s) return false;
    std::pop_heap(heap_.begin(), heap_.begin() + heap_len_, later_);
    const int idx = heap_[--heap_len_];
    const Slot& s = slots_[idx];
    n = s.n;
    std::memcpy(out, s.bytes, s.n);
    free_[free_len_++] = idx;
    return true;
  }
  // Due time of the next frame; a large value when none waits.
  double next_due() const { return heap_len_ == 0 ? 1e300 : slots_[heap_[0]].t; }
  int waiting() const { return heap_len_; }
  // Frames waiting are lost (an unplug); returns how many.
  int clear() {
    const int lost = heap_len_;
    heap_len_ = 0;
    free_len_ = kCapacity;
    for (int i = 0; i < kCapacity; ++i) free_[i] = kCapacity - 1 - i;
    fifo_t_ = -1e300;
    return lost;
  }
  const FrameFaultStats& stats() const { return stats_; }

 private:
  struct Slot {
    double t = 0.0;
    uint64_t serial = 0;
    size_t n = 0;
    uint8_t bytes[kMaxFrame] = {};
  };
  double u() { return dist_(rng_); }
  bool schedule(const uint8_t* data, size_t n, double t, bool corrupt, size_t at, uint8_t x) {
    if (free_len_ == 0) {
      ++stats_.overflowed;
      return false;
    }
    const int idx = free_[--free_len_];
    Slot& s = slots_[idx];
    s.t = t;
    s.serial = serial_++;
    s.n = n;
    std::memcpy(s.bytes, data, n);
    if (corrupt) s.bytes[at] ^= x;
    heap_[heap_len_++] = idx;
    std::push_heap(heap_.begin(), heap_.begin() + heap_len_, later_);
    return true;
  }
  struct Later {
    const FaultyFrameLine* line;
    bool operator()(int a, int b) const {
      const Slot& x = line->slots_[a];
      const Slot& y = line->slots_[b];
      return x.t != y.t ? x.t > y.t : x.serial > y.serial;
    }
  };

  FrameFaults faults_;
  std::mt19937_64 rng_{1};
  std::uniform_real_distribution<double> dist_{0.0, 1.0};
  std::array<Slot, kCapacity> slots_{};
  std::array<int, kCapacity> heap_{};
  std::array<int, kCapacity> free_{};
  int heap_len_ = 0, free_len_ = 0;
  uint64_t serial_ = 0;
  double fifo_t_ = -1e300;
  Later later_{this};
  FrameFaultStats stats_;
};

}  // namespace feedloop::protocol
