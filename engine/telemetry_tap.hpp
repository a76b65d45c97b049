// What the motion executor tells an observer (the flight recorder, a benchmark, a trace export)
// while it runs. Every call but on_planned_move() comes from the servo thread and must be RT-safe
// (push into a lock-free ring; no allocation, no locks, no I/O). Default: ignore.
#pragma once

#include <array>
#include <cstdint>

#include "engine/device_loop_telemetry.hpp"
#include "planner/move.hpp"

namespace feedloop::engine {

// One servo period while motion is anchored, and for MotionOptions::settle_tail_s after it ends
// (every joint; NaN where a value does not exist).
struct ServoSample {
  double host_time_s = 0.0;   // machine clock at the cycle
  double print_time_s = 0.0;  // print time whose targets this cycle commanded
  std::array<double, 4> desired_mm{};  // r: planned joint (carriage) positions at print_time_s
  std::array<double, 4> command_mm{};  // u: motor command (feedforward + PI) for print_time_s
  std::array<double, 4> encoder_mm{};  // latest encoder reading, joint coordinates (NaN: none)
  std::array<double, 4> steps_mm{};    // steps generated so far x mm per step
  std::array<double, 3> nozzle_mm{};   // planned nozzle position at print_time_s
};

enum class ServoEventKind : uint8_t {
  kLostSteps,      // motor vs encoder beyond the threshold: size_mm lost, position recovered
  kEncoderFault,   // implausible jump or stale reports: motion stopped
  kFollowingError, // error beyond max_following_error_mm: motion stopped
  kMcuFault,       // an MCU disconnected or stopped
  kDeadlineMiss,   // the servo thread woke more than a period late (size_mm holds the lateness, s)
};
const char* to_string(ServoEventKind k);

struct ServoEvent {
  ServoEventKind kind = ServoEventKind::kLostSteps;
  double print_time_s = 0.0;
  int joint = -1;
  double size_mm = 0.0;
};

// One encoder sample as the MCU took it: on the joint's MCU clock (the step runs' time line), in
// the executor's frame (the steps' position, as ServoSample::encoder_mm).
struct EncoderReading {
  int joint = 0;
  int64_t clock = 0;
  double mm = 0.0;
};

class TelemetryTap {
 public:
  virtual ~TelemetryTap() = default;
  virtual void on_planned_move(const planner::PlannedMove& /*m*/) {}  // planner thread
  virtual void on_servo_sample(const ServoSample& /*s*/) {}           // servo thread, RT-safe
  virtual void on_servo_event(const ServoEvent& /*e*/) {}             // servo thread, RT-safe
  // Each device loop's LOOP_REPORT (control.loop: device; 100 Hz per joint), as it arrives.
  virtual void on_device_loop_report(const DeviceLoopReport& /*r*/) {}  // servo thread, RT-safe
  // Every encoder sample the MCUs reported (the servo period's rate), in arrival order; a joint
  // that has them is recorded from them, not from the cycles' latest reading.
  virtual void on_encoder_sample(const EncoderReading& /*r*/) {}  // servo thread, RT-safe
};

inline const char* to_string(ServoEventKind k) {
  switch (k) {
    case ServoEventKind::kLostSteps: return "lost_steps";
    case ServoEventKind::kEncoderFault: return "encoder_fault";
    case ServoEventKind::kFollowingError: return "following_error";
    case ServoEventKind::kMcuFault: return "mcu_fault";
    case ServoEventKind::kDeadlineMiss: return "deadline_miss";
  }
  return "?";
}

}  // namespace feedloop::engine
