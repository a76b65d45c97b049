// Small helpers for real-time set-up; each returns a Status and the caller warns and goes on
// when one is not permitted (ros2_control's realtime_helpers idea).
#pragma once

#include "core/result.hpp"

namespace feedloop::engine {

// SCHED_FIFO at `priority` (1..99) for the calling thread.
Status make_thread_realtime(int priority);
// mlockall(MCL_CURRENT | MCL_FUTURE): no page faults in the servo loop.
Status lock_memory();

}  // namespace feedloop::engine
