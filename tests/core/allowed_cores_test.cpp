#include "core/allowed_cores.hpp"

#include <gtest/gtest.h>
#include <pthread.h>
#include <sched.h>

#include <thread>

namespace feedloop::core {
namespace {

TEST(AllowedCores, TheAffinityMasksCores) {
  cpu_set_t set;
  CPU_ZERO(&set);
  ASSERT_EQ(sched_getaffinity(0, sizeof(set), &set), 0);
  EXPECT_EQ(allowed_cores(), static_cast<uint32_t>(CPU_COUNT(&set)));
}

// A thread pinned to one core (as `taskset -c 0` pins a process) is allowed one.
TEST(AllowedCores, APinnedThreadIsAllowedOne) {
  cpu_set_t mine;
  CPU_ZERO(&mine);
  ASSERT_EQ(sched_getaffinity(0, sizeof(mine), &mine), 0);
  int first = -1;
  for (int c = 0; c < CPU_SETSIZE && first < 0; ++c)
    if (CPU_ISSET(c, &mine)) first = c;
  ASSERT_GE(first, 0);
  uint32_t seen = 0;
  std::thread t([&] {
    cpu_set_t one;
    CPU_ZERO(&one);
    CPU_SET(first, &one);
    if (pthread_setaffinity_np(pthread_self(), sizeof(one), &one) == 0) seen = allowed_cores();
  });
  t.join();
  EXPECT_EQ(seen, 1u);
}

}  // namespace
}  // namespace feedloop::core
