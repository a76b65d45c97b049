#include "engine/realtime.hpp"

#include <pthread.h>   // pthread_setschedparam
#include <sched.h>     // SCHED_FIFO
#include <sys/mman.h>      // mlockall
#include <sys/resource.h>  // getrlimit
#include <unistd.h>        // geteuid

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
  // With a finite RLIMIT_MEMLOCK (an unprivileged user: 8 MB by default), mlockall succeeds while
  // the process is small, and then every later mapping must fit the limit: the next thread's
  // stack does not, and std::thread fails. Lock only when the limit cannot be hit.
  rlimit lim{};
  if (geteuid() != 0 && getrlimit(RLIMIT_MEMLOCK, &lim) == 0 && lim.rlim_cur != RLIM_INFINITY)
    return Error{"memory not locked: RLIMIT_MEMLOCK is " + std::to_string(lim.rlim_cur / 1024) +
                 " kB (run with CAP_IPC_LOCK, or LimitMEMLOCK=infinity in the systemd unit)"};
  if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0)
    return Error{std::string("cannot lock memory: ") + std::strerror(errno) +
                 " (needs CAP_IPC_LOCK or LimitMEMLOCK=infinity)"};
  return Status::Ok();
}

}  // namespace feedloop::engine
