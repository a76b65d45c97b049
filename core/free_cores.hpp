// How many of the cores this process may run on are free right now: the cores of its affinity
// mask less the other threads the kernel has runnable (/proc/stat's procs_running, the least of a
// few samples half a millisecond apart, since a busy process is runnable in every sample and a
// short-lived one is not). Batch mode splits its joints across two threads only when a second core
// is free: on a core shared with another busy process the split costs more than it gains
// (docs/decisions.md, "Batch mode: a second thread only on a free core").
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>

namespace feedloop::core {

// procs_running from the text of /proc/stat; nullopt when absent or malformed.
std::optional<uint32_t> procs_running_from_stat(std::string_view stat_text);

// Cores of the affinity mask not held by another runnable thread (at least 1: the caller's own).
// Without /proc/stat (not Linux, a restricted container): all the affinity mask's cores.
uint32_t free_cores();

}  // namespace feedloop::core
