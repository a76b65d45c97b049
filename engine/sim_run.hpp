// Runs G-code through the daemon's own pipeline (Machine, MotionExecutor, McuBridge with the mock
// MCUs driving the plant simulator) in virtual time and records every servo period: what the
// control benchmarks (bench/control), the closed-loop tests and `feedloop batch --export-trace`
// measure. Nothing here is a copy of the pipeline: it is the daemon's, on a VirtualClock.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "config/machine_config.hpp"
#include "core/result.hpp"
#include "engine/device_loop_telemetry.hpp"
#include "engine/telemetry_tap.hpp"

namespace feedloop::engine {

struct SimRunSample;

// Fault injection: at print time `at_s` the next `steps` steps of `joint` are lost on their way
// to the motor (what a skipped step looks like from the encoder).
struct LostStepInjection {
  double at_s = 0.0;
  int joint = 0;
  int64_t steps = 0;
};

// Fault injection: from print time `at_s` on, `joint`'s encoder reads offset_mm more than the
// carriage (a glitch that stays).
struct EncoderGlitchInjection {
  double at_s = 0.0;
  int joint = 0;
  double offset_mm = 0.0;
};

// A host stall: at `at_s` of virtual time after the MCUs are ready, the planner and the motion
// stage stop for `duration_s` (no servo cycle runs; the MCUs and the plant go on, and the link is
// serviced through the gap when the stage wakes, as the bridge does after any late cycle).
struct HostStall {
  double at_s = 0.0;
  double duration_s = 0.0;
};

struct SimRunOptions {
  double settle_s = 0.05;        // keep sampling this long after the motion's planned end
  double timeout_s = 600.0;      // of virtual time
  bool keep_samples = true;      // false: only the summary figures
  // Called with every sample as it is produced (streaming, e.g. a trace export); may be empty.
  std::function<void(const SimRunSample&)> on_sample;
  // Called now and then with the fraction of the lines executed (0..1); may be empty.
  std::function<void(double fraction)> on_progress;
  std::vector<LostStepInjection> lose_steps;
  std::vector<EncoderGlitchInjection> encoder_glitches;
  std::vector<HostStall> stalls;  // in time order
  double idle_before_s = 0.0;     // the machine runs idle this long after the MCUs are ready
};

// One servo period of the run: what the pipeline commanded and what the simulated machine did.
struct SimRunSample {
  ServoSample servo;                     // desired / command / encoder / steps, per joint
  std::array<double, 4> actual_mm{};     // ground truth: carriage (joint) positions of the plant
  std::array<double, 3> actual_nozzle_mm{};  // ground truth nozzle (Cartesian: the carriages)
};

struct SimRunResult {
  std::vector<SimRunSample> samples;     // every servo period while motion was anchored
  std::vector<ServoEvent> events;        // lost steps detected, encoder faults, ...
  std::array<int64_t, 4> lost_full_steps{};  // ground truth from the plant (0 for an ideal joint)
  std::array<int64_t, 4> slip_events{};      // ground truth: slips either way (lost_full_steps is net)
  uint64_t late_cycles = 0;                  // cycles that found the commands nearly run out (plan paused)
  uint64_t commands = 0;                 // G-code lines executed
  uint64_t rejected = 0;                 // lines rejected (with the first error in `error`)
  double motion_time_s = 0.0;            // planned print time from first move start to last end
  uint64_t deadline_misses = 0;
  // The machine's own figures at the end (what the daemon's status shows): lost-step events
  // detected (host detector or device loops), e_t from the encoders (mean, max over the reports).
  uint64_t lost_step_events = 0;
  double tracking_error_mean_mm = 0.0, tracking_error_max_mm = 0.0;
  uint64_t tracking_error_samples = 0;
  uint64_t faults = 0;                   // encoder faults, following-error trips, MCU faults
  DeviceLoopTelemetrySet device_loops{}; // each joint's device loop as its reports told it
  std::string error;                     // first rejected line or fault (empty: none)
};

// The config's machine must use mock MCUs (the simulator). Errors: a config that cannot be built.
Result<SimRunResult> run_simulated(const config::MachineConfig& cfg,
                                   const std::vector<std::string>& gcode_lines,
                                   const SimRunOptions& options = {});

}  // namespace feedloop::engine
