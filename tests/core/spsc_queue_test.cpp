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

}  // namespace feedloop
