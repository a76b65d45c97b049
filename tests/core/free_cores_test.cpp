#include "core/free_cores.hpp"

#include <gtest/gtest.h>
#include <sched.h>

#include <thread>

namespace feedloop::core {
namespace {

TEST(FreeCores, ProcsRunningIsReadFromProcStat) {
  const char* stat =
      "cpu  10 0 20 300 0 0 0 0 0 0\n"
      "intr 1 2 3\n"
      "ctxt 12345\n"
      "procs_running 3\n"
      "procs_blocked 0\n";
  EXPECT_EQ(procs_running_from_stat(stat), 3u);
  EXPECT_EQ(procs_running_from_stat("procs_running 17"), 17u);  // last line, no newline
}

TEST(FreeCores, AMissingOrMalformedCountIsNoCount) {
  EXPECT_FALSE(procs_running_from_stat(""));
  EXPECT_FALSE(procs_running_from_stat("cpu 1 2 3\nprocs_blocked 0\n"));
  EXPECT_FALSE(procs_running_from_stat("procs_running \n"));
  EXPECT_FALSE(procs_running_from_stat("procs_running x\n"));
  EXPECT_FALSE(procs_running_from_stat("procs_running -1\n"));
  EXPECT_FALSE(procs_running_from_stat("procs_runningx 3\n"));
}

TEST(FreeCores, BetweenOneAndTheAffinityMasksCores) {
  cpu_set_t set;
  CPU_ZERO(&set);
  ASSERT_EQ(sched_getaffinity(0, sizeof(set), &set), 0);
  const auto allowed = static_cast<uint32_t>(CPU_COUNT(&set));
  const uint32_t free = free_cores();
  EXPECT_GE(free, 1u);
  EXPECT_LE(free, allowed);
}

}  // namespace
}  // namespace feedloop::core
