// The transport of a serial or USB MCU entry (mcus[], heater_mcus[]): one place that turns a
// config entry into a drivers::Transport. Mock entries are simulated by their owners (McuBridge,
// the heater link), which build the virtual MCU behind them.
#pragma once

#include <memory>

#include "config/machine_config.hpp"
#include "drivers/transport.hpp"

namespace feedloop::engine {

// io_priority: the transport I/O thread's SCHED_FIFO priority (0: the default scheduler).
// nullptr for a mock entry.
std::unique_ptr<drivers::Transport> make_hardware_transport(const config::McuConfig& mc, int io_priority);

}  // namespace feedloop::engine
