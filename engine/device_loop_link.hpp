// The host's side of the device loop (control.loop: device; docs/protocol.md section 11; issue 13
// item 2): per joint with an encoder, the loop's parameters from the config (CONFIGURE_LOOP,
// applied at a stated MCU clock), the desired carriage trajectory r(t) streamed as bounded-error
// knots (QUEUE_TARGET) as the motion stage samples it, `queue_ahead_ms` ahead, and the loop's
// events and reports read back (slips, trips, encoder faults; e, y, correction, tick cost).
//
// The PI itself runs on the MCU, on the MCU's clock: a host stall shorter than the lead changes
// nothing in the print (the MCU has the steps and r(t) it needs); a longer one ends in the device's
// controlled stop (r's queue runs out: LOOP_EVENT stop started, reason "target horizon").
//
// Positions on the wire are nm in the MCU's frame (its step counter and encoder count from the
// power-on zero); the host's joint frame differs from it by the encoder offset the motion stage
// sets at its resync, so the motion stage passes r already in the encoder's frame.
// Owner: the servo thread (McuBridge). Allocation-free after configure().
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <string>

#include "config/machine_config.hpp"
#include "core/result.hpp"
#include "drivers/device/loop_params.hpp"
#include "drivers/host/mcu_session.hpp"
#include "drivers/protocol/loop_messages.hpp"
#include "drivers/protocol/target_codec.hpp"
#include "engine/config_mapping.hpp"
#include "engine/device_loop_telemetry.hpp"

namespace feedloop::engine {

class DeviceLoopLink {
 public:
  static constexpr int kKnotsPerMessage = 16;  // well inside one frame (4-8 bytes per knot)

  // The loop parameters of `joint` from the config; disabled when the config's control is not
  // mode pi with loop device, or the joint has no encoder. `mm_per_count` and `mm_per_step` are
  // the joint's encoder and step sizes, `clock_hz` its MCU's clock.
  static device::LoopParams params_from_config(const config::MachineConfig& cfg, int joint,
                                               double mm_per_count, double mm_per_step,
                                               double clock_hz);

  void set_joint(int joint, uint8_t motor, const device::LoopParams& params);
  bool enabled(int joint) const { return j_[static_cast<size_t>(joint)].params.enabled; }
  bool any_enabled() const;

  // After every (re)identification: CONFIGURE_LOOP for each loop joint on its session, active from
  // activation_clock (an MCU clock of that session). Forgets the targets of a previous run.
  void configure(int joint, drivers::McuSession& session, int64_t activation_clock);
  // CONFIGURE_LOOP with the loop disabled from activation_clock on (the device executes the host's
  // steps only, and drops its queued targets): before a homing moves the axis with its own steps.
  void disable(int joint, drivers::McuSession& session, int64_t activation_clock);

  // One sample of r (mm, the MCU's frame) at `clock` (that MCU's ticks, increasing). Knots go out
  // in messages of kKnotsPerMessage; flush() sends what is pending.
  void push_target(int joint, drivers::McuSession& session, int64_t clock, double r_mm);
  // Sends the knots emitted so far; `end_of_motion` also emits the last sample (the motion ended:
  // r holds there).
  void flush(int joint, drivers::McuSession& session, bool end_of_motion);

  // Drains `session`'s loop reports and events (the session of MCU `mcu`): telemetry updated for
  // the joints it drives, events copied to out[0..cap) with their joint (returns their count),
  // reports appended to reports[*n_reports..reports_cap) (clock set, host_time_s left to the
  // caller; reports beyond the capacity only update the telemetry).
  struct JointEvent {
    int joint = -1;
    device::LoopEvent event;
  };
  size_t collect(drivers::McuSession& session, int mcu, const std::array<int, kJoints>& joint_mcu,
                 const std::array<int, kJoints>& joint_motor, JointEvent* out, size_t cap,
                 DeviceLoopReport* reports, size_t reports_cap, size_t* n_reports);

  const DeviceLoopTelemetry& telemetry(int joint) const {
    return j_[static_cast<size_t>(joint)].telemetry;
  }
  double mm_per_count(int joint) const { return j_[static_cast<size_t>(joint)].mm_per_count; }
  // Reports collect() could not hand out (its buffer was full); they updated the telemetry only.
  uint64_t reports_overflow() const { return reports_overflow_; }

 private:
  struct Joint {
    device::LoopParams params;
    uint8_t motor = 0;
    double mm_per_count = 0.0;
    protocol::TargetCompressor compressor;
    std::array<device::TargetKnot, kKnotsPerMessage> pending{};
    int pending_count = 0;
    int64_t last_clock = INT64_MIN;
    DeviceLoopTelemetry telemetry;
  };
  void send_pending(Joint& j, drivers::McuSession& session);
  std::array<Joint, kJoints> j_{};
  uint64_t reports_overflow_ = 0;
};

// "x: slip of 1 cycle(s) (0.679 mm) at MCU clock 123" etc.: one event as a log line.
std::string describe_loop_event(const std::string& joint, const device::LoopEvent& e);

}  // namespace feedloop::engine
