#include "engine/realtime.hpp"

#include <pthread.h>   // pthread_setschedparam
#include <sched.h>     // SCHED_FIFO
#include <sys/mman.h>  // mlockall

#include <cstring>  // strerror
#include <string>

namespace feedloop::engine {

Status make_thread_realtime(int priority) {
  sched_param param{};
  param.sched_priority = priority;
  const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param);
  if (rc != 0)
    return Error{"cannot set SCHED_FIFO priority " + std::to_string(priority) + ": " +
                 std::strerror(rc) + " (needs CAP_SYS_NICE or LimitRTPRIO)"};
  return Status::Ok();
}

Status lock_memory() {
  if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0)
    return Error{std::string("cannot lock memory: ") + std::strerror(errno) +
                 " (needs CAP_IPC_LOCK or LimitMEMLOCK=infinity)"};
  return Status::Ok();
}

}  // namespace feedloop::engine
