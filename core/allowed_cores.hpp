// How many cores the calling thread may run on: the cores of its affinity mask (taskset, cgroup
// cpusets), at least 1. Batch mode steps on two threads when there are two
// (docs/decisions.md, "Batch mode: two threads share the lanes").
#pragma once

#include <cstdint>

namespace feedloop::core {

uint32_t allowed_cores();

}  // namespace feedloop::core
