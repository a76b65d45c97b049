// Names of MCU error codes for messages to the user.
#include "drivers/protocol/messages.hpp"

namespace feedloop::protocol {

const char* mcu_error_name(McuError e) {
  switch (e) {
    case McuError::kNone: return "none";
    case McuError::kVersionMismatch: return "protocol version mismatch";
    case McuError::kQueueUnderrun: return "step queue underrun (step time already in the past)";
    case McuError::kWatchdog: return "watchdog: no message from the host while enabled";
    case McuError::kQueueOverflow: return "step queue overflow";
    case McuError::kBadMessage: return "malformed or unknown message";
    case McuError::kEmergencyStop: return "emergency stop";
    case McuError::kNotIdentified: return "command before identify";
    case McuError::kBatchOverlap: return "step batch overlaps the previous one";
    case McuError::kFollowingError: return "device loop: following error beyond the limit (controlled stop)";
    case McuError::kEncoderFault: return "device loop: implausible encoder readings (controlled stop)";
    case McuError::kTargetUnderrun: return "device loop: target trajectory ran out while moving (controlled stop)";
    case McuError::kBadLoopConfig: return "device loop: configuration refused";
    case McuError::kTargetOverflow: return "device loop: target queue full or clocks not increasing";
  }
  return "unknown error";
}

}  // namespace feedloop::protocol
