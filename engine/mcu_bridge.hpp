// The machine's MCUs behind the step pipeline (DESIGN.md "The microcontroller side"): for each
// McuConfig one host McuSession on its transport; for `mock` transports also the VirtualMcu (with
// a drifting clock) and the simulated plant it drives (engine/simulated_plant.hpp, built by the
// simulated transport's factory engine/simulated_printer.hpp: a gantry axis per Cartesian joint or
// one delta plant for the carriages; an ideal motor for the extruder).
//
//   StepPipeline --StepBatch--> McuBridge::on_batch --> McuSession --> Transport (mock: faults)
//        --> VirtualMcu --MotorPort--> plant;   encoder reports, clock sync, errors flow back.
//
// Servo thread: service(now) once per period (from MotionExecutor::servo_cycle): the sessions
// (frames into the transports' send queues, received bytes out of theirs; serial and USB move the
// bytes on their own I/O threads, drivers/transport/queued_transport.hpp, where the clock sync's
// fit runs too), virtual MCUs and plants advanced to now (mock: in-process, on this thread),
// encoder samples, faults. tick_map(joint) gives the clock sync's host-time -> MCU-tick map used
// for every step time. Nothing here waits on a device.
// Faults: an MCU that disconnects or stops latches fault() with a message naming it; every other
// MCU gets an emergency stop. When every link is back, all MCUs are re-identified, the clocks
// re-synchronised, and the fault clears (the executor then restarts from the planned position;
// the real machine has lost its position and should be homed).
// Real time: nothing on the steady-state path allocates (the sessions' rings, the mock transport's
// frame pools, the encoder sample buffers swapped with the sessions'; tests/engine_sim). The first
// open of a serial/USB link waits for its I/O thread's attempt (start(), before motion); every
// later reopen is asked of the I/O thread and never waited for.
#pragma once

#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "config/machine_config.hpp"
#include "core/result.hpp"
#include "core/seqlock.hpp"
#include "drivers/device/virtual_mcu.hpp"
#include "drivers/host/homing.hpp"
#include "drivers/host/mcu_session.hpp"
#include "drivers/transport/mock_transport.hpp"
#include "engine/config_mapping.hpp"
#include "engine/device_loop_link.hpp"
#include "engine/servo_backend.hpp"
#include "engine/shared_heater_port.hpp"
#include "engine/simulated_plant.hpp"

namespace feedloop::engine {

class SimulatedHeaterBoard;  // engine/simulated_printer.hpp

struct McuBridgeOptions {
  double drift_ppm = 50.0;        // virtual MCU i runs fast (even i) or slow (odd i) by this much
  double clock_offset_s = 3.7;    // virtual MCU i's clock reads (t + (i + 1) clock_offset_s) rate
  drivers::MockFaults faults;     // every mock link
  double sync_settle_s = 1.0;     // clock queries after identify before motion may start
  double watchdog_s = 0.5;        // MCU watchdog (no host message -> stop)
  double restart_period_s = 0.5;  // after a fault: how often to retry re-identifying
  double io_slice_s = 50e-6;      // virtual MCUs: links serviced at this granularity within a period
  size_t step_ring = 1 << 16;     // per joint: steps in flight tracked for the timing figures
};

// Step timing on the plant side, per joint (simulation only): each executed step against the
// host time the pipeline intended for it (the compressed tick mapped back through the clock
// estimate in use when its batch was sent).
struct JointTiming {
  uint64_t steps_sent = 0;         // steps in batches handed to the MCU
  uint64_t hash_sent = device::kStepHashSeed;  // step_hash over what was sent
  uint64_t steps_executed = 0;     // steps the plant received
  uint64_t unexpected_steps = 0;   // executed steps that were never sent (must stay 0)
  uint64_t device_steps = 0;       // steps the device loop added (corrections, stop ramps)
  double max_time_err_us = 0.0;    // max |true step time - intended host time|
  uint64_t homing_steps = 0;       // steps of a homing sequence (streamed by it, not the pipeline)
};

// One joint's last homing through its endstop (simulation adds the plant's ground truth).
struct HomingReport {
  double homed_mm = NAN;          // the host's homed motor position (HomingResult::position_mm)
  double true_carriage_mm = NAN;  // the simulated carriage's true position then (NaN: real MCU;
                                  // CoreXY: the Cartesian carriage's, from both belts' ends)
  double first_touch_mm = NAN;    // the fast approach's trigger, in the final frame
  uint64_t count = 0;             // homings of this joint so far
  int64_t relay_lag_steps = 0;    // CoreXY: the second motor's steps after the first stopped
  // Carriage-referenced (a joint with an encoder, MCU protocol v4): homed_mm is the endstop plus
  // the encoder's travel from the trigger to the rest; steps_homed_mm is what the steps alone gave
  // (the endstop plus the steps after the trigger). Their difference is the carriage's lag behind
  // the steps at the trigger, which the steps-referenced frame keeps as an offset.
  bool encoder_referenced = false;
  double steps_homed_mm = NAN;
};

class McuBridge final : public stepgen::BatchSink, public ServoBackend {
 public:
  static Result<std::unique_ptr<McuBridge>> create(const config::MachineConfig& cfg,
                                                   const McuBridgeOptions& options = {});
  ~McuBridge() override;
  McuBridge(const McuBridge&) = delete;
  McuBridge& operator=(const McuBridge&) = delete;

  // Opens every link and identifies every MCU (host time now_s). The first service() does it
  // when nobody called it.
  Status start(double now_s);

  // ServoBackend (servo thread, except where noted there).
  void service(double now_s) override;
  bool ready() const override { return ready_.load(std::memory_order_acquire); }
  stepgen::TickMap tick_map(int joint) const override;
  bool fault() const override { return fault_.load(std::memory_order_acquire); }
  void fault_message(char* out, size_t cap) const override;
  double encoder_mm(int joint) const override;
  unsigned long long encoder_samples() const override { return encoder_samples_.load(std::memory_order_relaxed); }
  unsigned long long encoder_reports(int joint) const override;
  double encoder_time_s(int joint) const override;
  double encoder_sample_time_s(int joint, int64_t mcu_clock) const override;
  double encoder_delay_s(int joint) const override {
    return joint >= 0 && joint < static_cast<int>(kJoints)
               ? encoder_delay_s_[static_cast<size_t>(joint)]
               : 0.0;
  }
  void links(LinkTelemetrySet& out) const override { out = links_.load(); }
  bool device_loop(int joint) const override { return loop_link_.enabled(joint); }
  void queue_target(int joint, int64_t mcu_clock, double r_mm) override;
  void flush_targets(bool end_of_motion) override;
  size_t take_device_events(ServoEvent* out, size_t cap) override;
  unsigned long long device_lost_step_events() const override {
    return device_slips_.load(std::memory_order_relaxed);
  }
  void device_loops(DeviceLoopTelemetrySet& out) const override { out = loop_telemetry_.load(); }
  size_t take_device_reports(DeviceLoopReport* out, size_t cap) override;
  size_t take_encoder_samples(EncoderReading* out, size_t cap) override;
  // Encoder samples that arrived while the buffer for take_encoder_samples() was full.
  uint64_t encoder_samples_dropped() const { return encoder_readings_dropped_; }
  // The device loop's last report of `joint` (servo thread's data: read when it is not running).
  const DeviceLoopTelemetry& device_loop_telemetry(int joint) const { return loop_link_.telemetry(joint); }
  // Reports that arrived while the buffer for take_device_reports() was full (not taken in time).
  uint64_t device_reports_dropped() const { return loop_link_.reports_overflow(); }

  // Homing through the endstops (ServoBackend; docs/homing.md).
  bool can_home(int joint) const override {
    return joint >= 0 && joint < kJoints && homing_[static_cast<size_t>(joint)] != nullptr;
  }
  bool start_homing(unsigned joint_mask, double now_s, char* why, size_t cap) override;
  void abort_homing(const char* why) override;
  void set_motors_enabled(unsigned joint_mask, bool on) override;
  HomingState homing_state() const override { return homing_state_; }
  double homed_position_mm(int joint) const override;
  double homing_shift_mm(int axis) const override;
  int64_t homing_last_step_clock(int joint) const override;
  void homing_error(char* out, size_t cap) const override;
  int endstop_state(int joint) const override;
  bool endstop_at_max(int joint) const override;
  // The last homing of `joint` (servo thread's data: read when it is not running, or after the
  // G28 returned).
  HomingReport homing_report(int joint) const;

  // Heaters and fans on the motion MCUs' links (ServoBackend): the messages of the MCUs that
  // drive some cross from the thermal thread through these ports (service() moves them).
  const SharedHeaterPorts* heater_ports() const override { return &heater_ports_; }
  // The simulated heater board a mock motion MCU hosts (nullptr: none; tests inject its faults).
  SimulatedHeaterBoard* simulated_heater_board(int mcu);

  // stepgen::BatchSink (servo thread): StepBatch::axis is the joint index.
  void on_batch(const stepgen::StepBatch& batch) override;

  // Inspection (tests, benchmarks; the servo thread's data: read when it is not running).
  int mcu_count() const { return static_cast<int>(mcus_.size()); }
  const std::string& mcu_name(int i) const;
  drivers::McuSession& session(int i);
  drivers::MockTransport* mock(int i);          // nullptr for a real transport
  const device::VirtualMcu* virtual_mcu(int i) const;  // nullptr for a real transport
  int mcu_of_joint(int joint) const { return joint_mcu_[static_cast<size_t>(joint)]; }
  int motor_of_joint(int joint) const { return joint_motor_[static_cast<size_t>(joint)]; }
  SimulatedPlant* plant() { return plant_.get(); }  // the simulated machine (engine/simulated_printer.hpp)
  const JointTiming& timing(int joint) const;
  // Simulation fault injection (servo thread / tests): the next `steps` steps the MCU executes on
  // `joint` never reach the motor, as if the stepper had skipped them.
  void inject_lost_steps(int joint, int64_t steps);
  // From now on `joint`'s encoder reads offset_mm more than the carriage (a glitch that stays: a
  // slipped read head, a count lost by the interface), rounded to whole counts.
  void inject_encoder_offset(int joint, double offset_mm);
  uint64_t batches_dropped() const { return batches_dropped_; }  // arrived while faulted
  uint64_t faults() const { return faults_total_; }
  uint64_t recoveries() const { return recoveries_; }
  // Every event so far (disconnects, MCU errors, recoveries), oldest first. Any thread.
  std::vector<std::string> events() const;

 private:
  struct Mcu;
  struct JointPort;
  McuBridge(const config::MachineConfig& cfg, const McuBridgeOptions& options);
  Status build(const config::MachineConfig& cfg);
  double sim_time(double host_s);
  void poll_all(double now_s);
  void collect(double now_s);
  void publish_links(double now_s);
  void latch_fault(const std::string& message);
  void log(std::string message);
  void service_heater_ports(double host_s);
  void publish_homed(int joint, double homed_mm, double steps_mm, bool by_encoder);
  double corexy_stall_homed_mm(int axis, double steps_mm);
  std::array<double, 2> corexy_index_homed_mm();

  McuBridgeOptions options_;
  std::vector<std::unique_ptr<Mcu>> mcus_;
  std::array<int, kJoints> joint_mcu_{{-1, -1, -1, -1}};
  std::array<double, kJoints> index_position_mm_{
      {NAN, NAN, NAN, NAN}};  // encoder-index homing's marks
  std::array<double, kJoints> index_period_mm_{};  // their spacing (CoreXY: along the belts)
  std::array<int, kJoints> joint_motor_{{0, 0, 0, 0}};
  std::array<std::string, kJoints> joint_names_;
  std::array<double, kJoints> encoder_mm_per_count_{};
  std::array<double, kJoints> encoder_delay_s_{};  // model.gantry.<axis>.encoder_delay_ms
  std::array<std::unique_ptr<JointPort>, kJoints> ports_;
  std::unique_ptr<SimulatedPlant> plant_;
  SharedHeaterPorts heater_ports_;  // the motion MCUs' with heaters (Mcu::heater_port)
  bool simulated_ = false;  // some MCU is a virtual one (mock transport)
  Seqlock<LinkTelemetrySet> links_;
  LinkTelemetrySet links_scratch_;  // servo thread: filled, then published
  double next_links_s_ = 0.0;

  // Servo thread state.
  enum class Phase { kStarting, kRunning, kFaulted };
  Phase phase_ = Phase::kStarting;
  bool started_ = false;
  double epoch_s_ = 0.0;  // host time of simulation time 0 (the sessions run on simulation time)
  bool have_epoch_ = false;
  double last_service_s_ = 0.0;
  double ready_since_s_ = -1.0;
  double next_restart_s_ = 0.0;
  uint64_t batches_dropped_ = 0, faults_total_ = 0, recoveries_ = 0;

  std::atomic<bool> ready_{false};
  std::atomic<bool> fault_{false};
  struct FaultText {
    char text[192] = {};
  };
  Seqlock<FaultText> fault_text_;
  std::array<std::atomic<double>, kJoints> encoder_mm_{};
  std::atomic<unsigned long long> encoder_samples_{0};
  std::array<std::atomic<unsigned long long>, kJoints> encoder_reports_{};
  std::array<std::atomic<double>, kJoints> encoder_time_s_{};
  std::vector<drivers::EncoderSample> sample_buffer_;  // servo thread (swapped with the sessions')
  DeviceLoopLink loop_link_;                           // servo thread
  std::atomic<unsigned long long> device_slips_{0};
  void configure_device_loops(double host_s);
  bool loops_configured_ = false;
  // Joints whose drivers M18/M84 switched off: no targets, their loops stay off until a motion or
  // a homing switches them on again (set_motors_enabled).
  unsigned motors_off_ = 0;
  std::array<ServoEvent, 32> device_events_{};  // since the last take_device_events()
  size_t device_event_count_ = 0;
  // LOOP_REPORTs since the last take_device_reports() (100 Hz per joint: a few per servo cycle).
  std::array<DeviceLoopReport, 64> device_reports_{};
  // Encoder samples since the last take_encoder_samples() (10 per report per joint: a few
  // reports per servo cycle).
  std::array<EncoderReading, 256> encoder_readings_{};
  size_t encoder_reading_count_ = 0;
  uint64_t encoder_readings_dropped_ = 0;
  size_t device_report_count_ = 0;
  void publish_loop_telemetry();
  Seqlock<DeviceLoopTelemetrySet> loop_telemetry_;  // published when reports arrive

  // Homing (servo thread; the sequences are built with the bridge: nothing allocates to start one).
  void poll_homing(double now_s);
  void poll_endstops(double now_s);
  void end_homing(HomingState state);
  bool begin_joint_homing(int joint, double now_s);
  bool start_pending_homings(double now_s);
  unsigned homing_started_ = 0;
  std::array<std::unique_ptr<drivers::HomingSequence>, kJoints> homing_;
  // The joints each sequence moves: its primary motor's and, CoreXY, the follower's (-1: none).
  std::array<std::array<int, 2>, kJoints> homing_joints_{};
  bool corexy_ = false;
  bool homing_uses_mcu(int seq, int mcu) const;
  void corexy_homed(int axis);  // a CoreXY sequence done: its axis's position, the other's shift
  std::array<double, 3> homing_shift_mm_{};   // servo thread: this homing's shifts (CoreXY)
  std::array<double, 3> homing_result_mm_{};  // servo thread: this homing's positions (CoreXY)
  unsigned homing_finished_ = 0;              // CoreXY: sequences whose result is taken
  std::array<std::atomic<int64_t>, kJoints> relay_lag_steps_{};
  std::array<bool, kJoints> endstop_max_{};
  unsigned homing_mask_ = 0;
  HomingState homing_state_ = HomingState::kIdle;
  double homing_settle_until_s_ = -1.0;
  char homing_error_[192] = {};
  std::array<std::atomic<double>, kJoints> homed_mm_{}, homed_truth_mm_{}, first_touch_mm_{};
  std::array<std::atomic<uint64_t>, kJoints> homing_count_{};
  std::array<std::atomic<double>, kJoints> steps_homed_mm_{};  // HomingReport::steps_homed_mm
  std::array<std::atomic<bool>, kJoints> encoder_referenced_{};
  std::array<std::atomic<int>, kJoints> endstop_state_{};  // -1 unknown, 0 open, 1 triggered
  double next_endstop_query_s_ = 0.0;

  mutable std::mutex events_mutex_;  // taken only when an event happens (rare, not steady state)
  std::vector<std::string> events_;
};

// The bridge as the executor's batch sink and servo backend, from a machine config.
Result<std::shared_ptr<McuBridge>> make_mcu_bridge(const config::MachineConfig& cfg,
                                                   const McuBridgeOptions& options = {});

}  // namespace feedloop::engine
