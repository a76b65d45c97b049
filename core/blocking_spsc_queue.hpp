// A bounded single-producer single-consumer queue whose ends block instead of spinning: a
// consumer that finds it empty, or a producer that finds it full, sleeps on a futex
// (std::atomic::wait) until the other side signals. Signals are batched so that two threads
// working at about the same rate do not wake each other once per item: the producer wakes a
// sleeping consumer when wake_batch items are waiting (or when it is full or closed), the
// consumer wakes a sleeping producer when the queue has drained to half.
//
// For threads whose timing does not matter (batch mode): a waiting side makes a system call.
// The real-time paths use SpscQueue's try_push/try_pop, which never block.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>

#include "core/spsc_queue.hpp"

namespace feedloop {

template <class T>
class BlockingSpscQueue {
 public:
  BlockingSpscQueue(size_t capacity, size_t wake_batch)
      : q_(capacity), wake_batch_(std::clamp<size_t>(wake_batch, 1, capacity)) {}

  // Producer. Waits while the queue is full.
  void push(const T& v) {
    while (!q_.try_push(v)) {
      const uint32_t seen = space_signal_.load(std::memory_order_acquire);
      producer_waiting_.store(true, std::memory_order_relaxed);
      std::atomic_thread_fence(std::memory_order_seq_cst);
      if (q_.size() < q_.capacity()) {  // the consumer made room meanwhile
        producer_waiting_.store(false, std::memory_order_relaxed);
        continue;
      }
      // A sleeping consumer was woken when wake_batch items were waiting; the queue is fuller.
      ++producer_waits_;
      space_signal_.wait(seen, std::memory_order_acquire);
      producer_waiting_.store(false, std::memory_order_relaxed);
    }
    std::atomic_thread_fence(std::memory_order_seq_cst);
    if (consumer_waiting_.load(std::memory_order_relaxed) && q_.size() >= wake_batch_)
      wake(data_signal_);
  }

  // Producer: no more items. Wakes the consumer, which drains the queue and then sees the end.
  void close() {
    closed_.store(true, std::memory_order_release);
    std::atomic_thread_fence(std::memory_order_seq_cst);
    wake(data_signal_);
  }

  // Consumer. Waits while the queue is empty and open; false once it is closed and drained.
  bool pop(T& out) {
    for (;;) {
      if (q_.try_pop(out)) {
        std::atomic_thread_fence(std::memory_order_seq_cst);
        if (producer_waiting_.load(std::memory_order_relaxed) && q_.size() <= q_.capacity() / 2)
          wake(space_signal_);
        return true;
      }
      if (closed_.load(std::memory_order_acquire)) return q_.try_pop(out);
      const uint32_t seen = data_signal_.load(std::memory_order_acquire);
      consumer_waiting_.store(true, std::memory_order_relaxed);
      std::atomic_thread_fence(std::memory_order_seq_cst);
      if (q_.empty() && !closed_.load(std::memory_order_acquire)) {
        ++consumer_waits_;
        data_signal_.wait(seen, std::memory_order_acquire);
      }
      consumer_waiting_.store(false, std::memory_order_relaxed);
    }
  }

  // Times each side went to sleep (read after the threads are joined).
  uint64_t producer_waits() const { return producer_waits_; }
  uint64_t consumer_waits() const { return consumer_waits_; }

 private:
  static void wake(std::atomic<uint32_t>& signal) {
    signal.fetch_add(1, std::memory_order_release);
    signal.notify_one();
  }

  SpscQueue<T> q_;
  size_t wake_batch_;
  std::atomic<uint32_t> data_signal_{0};   // bumped by the producer: items or the end
  std::atomic<uint32_t> space_signal_{0};  // bumped by the consumer: room
  std::atomic<bool> consumer_waiting_{false};
  std::atomic<bool> producer_waiting_{false};
  std::atomic<bool> closed_{false};
  uint64_t producer_waits_ = 0;  // producer thread only
  uint64_t consumer_waits_ = 0;  // consumer thread only
};

}  // namespace feedloop
