#include "core/allowed_cores.hpp"

#include <sched.h>

#include <algorithm>
#include <thread>

namespace feedloop::core {

uint32_t allowed_cores() {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof(set), &set) == 0)
    return static_cast<uint32_t>(std::max(1, CPU_COUNT(&set)));
  return std::max(1u, std::thread::hardware_concurrency());
}

}  // namespace feedloop::core
