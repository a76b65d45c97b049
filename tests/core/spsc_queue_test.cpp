#include "core/spsc_queue.hpp"

#include <gtest/gtest.h>

#include <thread>

namespace feedloop {

TEST(SpscQueue, RefusesWhenFullAndKeepsOrder) {
  SpscQueue<int> q(3);
  ASSERT_GE(q.capacity(), 3u);
  size_t pushed = 0;
  while (q.try_push(static_cast<int>(pushed))) ++pushed;
  EXPECT_EQ(pushed, q.capacity());
  int v = -1;
  for (size_t i = 0; i < pushed; ++i) {
    ASSERT_TRUE(q.try_pop(v));
    EXPECT_EQ(v, static_cast<int>(i));
  }
  EXPECT_FALSE(q.try_pop(v));
}

TEST(SpscQueue, TwoThreadsTransferEveryElementOnce) {
  SpscQueue<uint64_t> q(64);
  constexpr uint64_t kCount = 200000;
  std::thread producer([&] {
    for (uint64_t i = 1; i <= kCount;) {
      if (q.try_push(i)) ++i;
    }
  });
  uint64_t sum = 0, expected_next = 1, v = 0;
  while (expected_next <= kCount) {
    if (q.try_pop(v)) {
      ASSERT_EQ(v, expected_next);
      sum += v;
      ++expected_next;
    }
  }
  producer.join();
  EXPECT_EQ(sum, kCount * (kCount + 1) / 2);
}

// In-place filling (try_claim + commit) and consuming (front_mut + pop) across two threads: large
// elements, every one once, in order, none visible before its commit.
TEST(SpscQueue, ClaimCommitAndFrontPopAcrossThreads) {
  struct Big {
    uint64_t seq;
    uint8_t bytes[200];
  };
  SpscQueue<Big> q(16);
  Big* full_probe = nullptr;
  for (size_t i = 0; i < q.capacity(); ++i) {
    Big* b = q.try_claim();
    ASSERT_NE(b, nullptr);
    b->seq = i;
    q.commit();
  }
  full_probe = q.try_claim();
  EXPECT_EQ(full_probe, nullptr) << "a full queue offers no slot";
  Big out{};
  while (q.try_pop(out)) {
  }
  constexpr uint64_t kCount = 100000;
  std::thread producer([&] {
    for (uint64_t i = 1; i <= kCount;) {
      Big* b = q.try_claim();
      if (b == nullptr) continue;
      b->seq = i;
      for (auto& x : b->bytes) x = static_cast<uint8_t>(i);
      q.commit();
      ++i;
    }
  });
  uint64_t expected = 1;
  size_t torn = 0;
  while (expected <= kCount) {
    Big* b = q.front_mut();
    if (b == nullptr) continue;
    ASSERT_EQ(b->seq, expected);
    for (auto x : b->bytes) torn += x != static_cast<uint8_t>(expected);
    q.pop();
    ++expected;
  }
  producer.join();
  EXPECT_EQ(torn, 0u);
  EXPECT_TRUE(q.empty());
}

}  // namespace feedloop
