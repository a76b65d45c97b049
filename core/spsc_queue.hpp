// Bounded lock-free single-producer single-consumer queue. Storage is allocated once, at
// construction; push/pop never allocate and never block, so the real-time side may use them.
// The producer calls try_push (or try_claim + commit, to fill a large element in place) only, the
// consumer try_pop / front + pop only.
#pragma once

#include <atomic>
#include <cstddef>
#include <memory>
#include <new>
#include <optional>
#include <utility>

namespace feedloop {

template <class T>
class SpscQueue {
 public:
  // capacity is rounded up to a power of two.
  explicit SpscQueue(size_t capacity) {
    size_t c = 1;
    while (c < capacity + 1) c <<= 1;
    mask_ = c - 1;
    slots_ = std::make_unique<T[]>(c);
  }
  SpscQueue(const SpscQueue&) = delete;
  SpscQueue& operator=(const SpscQueue&) = delete;

  size_t capacity() const { return mask_; }

  // Producer side. False when full (nothing is written).
  bool try_push(const T& v) {
    const size_t head = head_.load(std::memory_order_relaxed);
    const size_t next = (head + 1) & mask_;
    if (next == tail_.load(std::memory_order_acquire)) return false;
    slots_[head] = v;
    head_.store(next, std::memory_order_release);
    return true;
  }

  // Producer side, in place: the next free slot (nullptr when full), published by commit(). Between
  // the two the producer writes the slot; nothing is visible to the consumer before commit().
  T* try_claim() {
    const size_t head = head_.load(std::memory_order_relaxed);
    if (((head + 1) & mask_) == tail_.load(std::memory_order_acquire)) return nullptr;
    return &slots_[head];
  }
  void commit() { head_.store((head_.load(std::memory_order_relaxed) + 1) & mask_, std::memory_order_release); }

  // Consumer side. False when empty.
  bool try_pop(T& out) {
    const size_t tail = tail_.load(std::memory_order_relaxed);
    if (tail == head_.load(std::memory_order_acquire)) return false;
    out = std::move(slots_[tail]);
    tail_.store((tail + 1) & mask_, std::memory_order_release);
    return true;
  }

  // Consumer side: the oldest element without removing it, or nullptr.
  const T* front() const {
    const size_t tail = tail_.load(std::memory_order_relaxed);
    if (tail == head_.load(std::memory_order_acquire)) return nullptr;
    return &slots_[tail];
  }

  // Consumer side: drops the oldest element (after front() returned it).
  void pop() {
    const size_t tail = tail_.load(std::memory_order_relaxed);
    if (tail == head_.load(std::memory_order_acquire)) return;
    tail_.store((tail + 1) & mask_, std::memory_order_release);
  }
  // Consumer side: the oldest element, mutable (e.g. to consume it in parts), or nullptr.
  T* front_mut() {
    const size_t tail = tail_.load(std::memory_order_relaxed);
    if (tail == head_.load(std::memory_order_acquire)) return nullptr;
    return &slots_[tail];
  }

  // Approximate from either side; exact from a quiescent one.
  size_t size() const {
    return (head_.load(std::memory_order_acquire) - tail_.load(std::memory_order_acquire)) & mask_;
  }
  bool empty() const { return size() == 0; }

 private:
  static constexpr size_t kCacheLine = 64;
  alignas(kCacheLine) std::atomic<size_t> head_{0};
  alignas(kCacheLine) std::atomic<size_t> tail_{0};
  std::unique_ptr<T[]> slots_;
  size_t mask_ = 0;
};

}  // namespace feedloop
