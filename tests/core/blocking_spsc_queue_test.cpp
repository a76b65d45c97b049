// BlockingSpscQueue: order and completeness across threads, the end of the stream, and that a
// side with nothing to do sleeps (counted waits) instead of spinning: a consumer waiting for a
// slow producer uses almost no CPU.
#include "core/blocking_spsc_queue.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <ctime>
#include <thread>

namespace feedloop {
namespace {

double thread_cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

TEST(BlockingSpscQueue, EveryItemOnceInOrderThenTheEnd) {
  for (size_t batch : {1u, 7u, 64u}) {
    BlockingSpscQueue<uint64_t> q(64, batch);
    constexpr uint64_t kCount = 300000;
    std::thread producer([&] {
      for (uint64_t i = 1; i <= kCount; ++i) q.push(i);
      q.close();
    });
    uint64_t expect = 1, v = 0;
    while (q.pop(v)) {
      ASSERT_EQ(v, expect) << "batch " << batch;
      ++expect;
    }
    producer.join();
    EXPECT_EQ(expect, kCount + 1) << "batch " << batch;
    EXPECT_FALSE(q.pop(v));  // stays at the end
  }
}

TEST(BlockingSpscQueue, ASlowProducerLetsTheConsumerSleep) {
  BlockingSpscQueue<int> q(16, 4);
  double consumer_cpu_s = 0.0;
  int got = 0;
  std::thread consumer([&] {
    const double c0 = thread_cpu_s();
    int v = 0;
    while (q.pop(v)) ++got;
    consumer_cpu_s = thread_cpu_s() - c0;
  });
  for (int i = 0; i < 40; ++i) {  // 40 items over ~200 ms, 10 wake-ups of the consumer
    q.push(i);
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  q.close();
  consumer.join();
  EXPECT_EQ(got, 40);
  EXPECT_GE(q.consumer_waits(), 5u);
  EXPECT_LE(q.consumer_waits(), 41u);
  EXPECT_LT(consumer_cpu_s, 0.02) << "the consumer spun while it waited";
}

TEST(BlockingSpscQueue, ASlowConsumerLetsTheProducerSleep) {
  BlockingSpscQueue<int> q(8, 8);
  double producer_cpu_s = 0.0;
  std::thread producer([&] {
    const double c0 = thread_cpu_s();
    for (int i = 0; i < 48; ++i) q.push(i);
    q.close();
    producer_cpu_s = thread_cpu_s() - c0;
  });
  int v = 0, got = 0;
  while (q.pop(v)) {
    EXPECT_EQ(v, got);
    ++got;
    std::this_thread::sleep_for(std::chrono::milliseconds(3));
  }
  producer.join();
  EXPECT_EQ(got, 48);
  EXPECT_GE(q.producer_waits(), 3u);
  EXPECT_LT(producer_cpu_s, 0.02) << "the producer spun while it waited";
}

}  // namespace
}  // namespace feedloop
