// What the device loops (control.loop: device; drivers/device/axis_loop.hpp) tell the host about
// themselves (issue 13 item 2): each LOOP_REPORT (100 Hz per joint) carries the loop's state, the
// error e = r - y and the encoder y at its last tick, the PI's correction u and the largest cost
// of one tick in the report's window (ns on the virtual MCU, cycles on a firmware).
//
// DeviceLoopReport is one report as the flight recorder and the telemetry tap get it;
// DeviceLoopTelemetry is what the host has heard of one joint's loop so far, for the JSON API's
// status. Both trivially copyable (the set is published through a Seqlock, read by any thread).
#pragma once

#include <array>
#include <cstdint>

namespace feedloop::engine {

inline constexpr int kDeviceLoopJoints = 4;  // = kJoints (engine/config_mapping.hpp)

// One LOOP_REPORT of one joint.
struct DeviceLoopReport {
  int joint = -1;
  int64_t clock = 0;           // the report's tick, on that joint's MCU clock (ticks)
  double host_time_s = 0.0;    // the same instant on the host clock (the clock sync's estimate)
  uint8_t state = 0;           // device::LoopState: 0 idle, 1 running, 2 stopping, 3 stopped
  double e_mm = 0.0;           // r - y at the tick
  double y_mm = 0.0;           // encoder position at the tick (the MCU's frame: mm from power-on)
  double correction_mm = 0.0;  // the PI's output u, added to the host's steps
  uint32_t tick_cost = 0;      // the window's largest cost of one tick, in the device's unit
  double tick_cost_us = 0.0;   // the same in us (virtual MCU: ns / 1000)
  uint64_t ticks = 0, deadline_misses = 0, encoder_rejects = 0, slips = 0;  // since configured
};

// The running figures of one joint's loop (reset when the loop is configured again).
struct DeviceLoopTelemetry {
  bool enabled = false;           // this joint's PI runs on its MCU
  uint8_t state = 0;              // device::LoopState at the last report
  uint64_t reports = 0;           // LOOP_REPORTs received
  double e_mm = 0.0;              // last report: r - y
  double y_mm = 0.0;              // last report: encoder (MCU frame)
  double correction_mm = 0.0;     // last report: the PI's output u
  double tick_cost_us = 0.0;      // last report: the window's largest tick cost
  double max_tick_cost_us = 0.0;  // largest tick cost of any window
  double sum_tick_cost_us = 0.0;  // sum of the windows' largest costs (mean = sum / reports)
  // |e| over the reports while the loop was running (sampled at 100 Hz, not every tick).
  double max_abs_e_mm = 0.0;
  double sum_abs_e_mm = 0.0;
  uint64_t running_reports = 0;
  double max_abs_correction_mm = 0.0;
  uint64_t ticks = 0, deadline_misses = 0, encoder_rejects = 0, slips = 0;

  double mean_abs_e_mm() const {
    return running_reports > 0 ? sum_abs_e_mm / static_cast<double>(running_reports) : 0.0;
  }
  double mean_tick_cost_us() const {
    return reports > 0 ? sum_tick_cost_us / static_cast<double>(reports) : 0.0;
  }
  // Folds one report in.
  void add(const DeviceLoopReport& r) {
    ++reports;
    state = r.state;
    e_mm = r.e_mm;
    y_mm = r.y_mm;
    correction_mm = r.correction_mm;
    tick_cost_us = r.tick_cost_us;
    if (r.tick_cost_us > max_tick_cost_us) max_tick_cost_us = r.tick_cost_us;
    sum_tick_cost_us += r.tick_cost_us;
    if (r.state == 1) {
      const double a = r.e_mm < 0.0 ? -r.e_mm : r.e_mm;
      if (a > max_abs_e_mm) max_abs_e_mm = a;
      sum_abs_e_mm += a;
      ++running_reports;
    }
    const double c = r.correction_mm < 0.0 ? -r.correction_mm : r.correction_mm;
    if (c > max_abs_correction_mm) max_abs_correction_mm = c;
    ticks = r.ticks;
    deadline_misses = r.deadline_misses;
    encoder_rejects = r.encoder_rejects;
    slips = r.slips;
  }
};

using DeviceLoopTelemetrySet = std::array<DeviceLoopTelemetry, kDeviceLoopJoints>;

inline const char* device_loop_state_name(uint8_t state) {
  switch (state) {
    case 0:
      return "idle";
    case 1:
      return "running";
    case 2:
      return "stopping";
    case 3:
      return "stopped";
  }
  return "?";
}

}  // namespace feedloop::engine
