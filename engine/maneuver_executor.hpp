// The motion back end of a drive: dc_servo machine (config/README.md): the output-maneuvering
// controller (maneuver/, output-maneuvering-cartesian Sect. III-C/D) follows the planner's
// piecewise-linear path on the Cartesian DC-motor printer (Sect. III-A), simulated in the servo
// thread. Voltages in, no steps, no MCUs.
//
//   planner thread: Interpreter -> Planner (lookahead) -> final moves -> waypoints with their
//                   corner weights k_n (Eq. 64-66) -> SpscQueue<StreamWaypoint>
//   servo thread:   SpscQueue -> PathWindow -> StreamServo (Eq. 45, 52, 56 with split steps)
//                   -> voltages held over the period -> plant (Eq. 19-20, RK4 substeps)
//
// The planner's final moves fix the geometry (waypoints, corners); the controller assigns its own
// speed along them (control.maneuver.path_speed_mm_s and speed_assignment), as the paper does: the
// moves' feedrates and trapezoids are not used. The end of each move is released as soon as the
// lookahead releases the move, as a provisional stop; the next move's direction fixes its corner
// weight, which travels with the next waypoint. The planner thread stays at most
// max_buffered_s of path (at the path speed) ahead of the servo.
//
// Safety: a tracking error |z_1| beyond control.max_following_error_mm stops motion (queued
// waypoints are dropped, the plant is held where it is) and motion commands are rejected with the
// reason until the daemon restarts.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "config/machine_config.hpp"
#include "core/result.hpp"
#include "core/spsc_queue.hpp"
#include "engine/machine.hpp"
#include "maneuver/stream.hpp"
#include "planner/interpreter.hpp"
#include "planner/kinematics.hpp"
#include "planner/lookahead.hpp"

namespace feedloop::engine {

struct ManeuverExecutorOptions {
  size_t window_capacity = 8192;      // waypoints the servo thread holds
  size_t queue_capacity = 4096;       // waypoints in flight from the planner thread
  double max_buffered_s = 1.0;        // planner ahead of the servo, in path time at the path speed
  double input_pause_flush_s = 0.05;  // release the lookahead's tail after this long without input
  double lead_mm = 10.0;              // keep at least this much path known ahead of the extruder
  double plant_substep_s = 1e-4;      // RK4 step of the simulated plant
};

// Figures the servo thread publishes (relaxed atomics). Errors follow Eq. 70 (cross-track: XY
// distance across the segment being followed), accumulated while the extruder follows the path.
struct ManeuverTelemetry {
  std::atomic<uint64_t> cycles{0};
  std::atomic<uint64_t> segments_entered{0};
  std::atomic<double> max_cross_track_mm{0.0};
  std::atomic<double> iae_cross_track_mm_s{0.0};  // integral of |cross-track| over path time
  std::atomic<double> max_error_mm{0.0};          // max |z_1| (3D, along-track included)
  std::atomic<double> path_time_s{0.0};           // time spent following the path (not holding)
  std::atomic<double> path_mm{0.0};               // distance along the path at theta
  std::atomic<double> pos_mm[3] = {0.0, 0.0, 0.0};  // nozzle relative to the print surface (plant)
  std::atomic<double> e_mm{0.0};
  std::atomic<double> max_voltage_v{0.0};         // max |V_x|, |V_y| commanded
  std::atomic<bool> holding{true};
  std::atomic<bool> faulted{false};
};

class ManeuverExecutor final : public CommandExecutor, private planner::MoveSink {
 public:
  // Errors: a config that is not drive: dc_servo with control.mode maneuver, or whose planner
  // section is invalid.
  static Result<std::unique_ptr<ManeuverExecutor>> create(const config::MachineConfig& cfg,
                                                          const ManeuverExecutorOptions& options = {});

  Status execute(const gcode::Command& cmd, const std::atomic<bool>& cancel) override;
  void position(double out_mm[4]) const override;
  void homed_axes(char out[4]) const override { interp_->homed_axes(out); }
  void set_extrude_guard(std::function<std::string()> guard) override {
    interp_->set_extrude_guard(std::move(guard));
  }
  void idle_tick(const std::atomic<bool>& cancel) override;
  void release_lookahead() override;
  void set_waiting_for_motion(bool waiting) override { waiting_.store(waiting); }
  void servo_cycle(int64_t now_ns, bool cancel) override;
  bool motion_pending() const override;
  bool may_advance_virtual(bool planner_busy) const override;
  void motion_status(MachineStatus& s) const override;

  const ManeuverTelemetry& telemetry() const { return telemetry_; }
  uint64_t moves_planned() const { return moves_.load(std::memory_order_relaxed); }
  double servo_period_s() const { return period_s_; }

 private:
  ManeuverExecutor(const config::MachineConfig& cfg, const planner::PlannerConfig& pcfg,
                   const ManeuverExecutorOptions& options);
  void on_move(const planner::PlannedMove& m) override;
  void on_event(const planner::PlannerEvent& e) override;
  void emit(const maneuver::StreamWaypoint& w);  // planner thread: to the servo thread
  double corner_k(const maneuver::Vec3& d_in, const maneuver::Vec3& d_out) const;
  double buffered_mm() const;
  void wait_for_room(const std::atomic<bool>& cancel);
  void wait_motion_done(const std::atomic<bool>& cancel);
  void stop_and_hold();  // servo thread

  ManeuverExecutorOptions options_;
  double period_s_;
  double max_following_error_m_;
  planner::PlannerConfig pcfg_;
  std::unique_ptr<planner::Kinematics> kin_;
  planner::Planner planner_;
  std::unique_ptr<planner::Interpreter> interp_;
  maneuver::CartesianDcPlant plant_;
  maneuver::ManeuverController ctl_;
  maneuver::StreamSpeed speed_;
  SpscQueue<maneuver::StreamWaypoint> queue_;

  // planner thread
  const std::atomic<bool>* cancel_ = nullptr;
  bool wait_done_ = false;  // M400 seen during execute()
  std::chrono::steady_clock::time_point last_command_{};
  maneuver::StreamWaypoint last_;  // the newest waypoint emitted (its k is provisional: a stop)
  maneuver::Vec3 last_dir_ = maneuver::Vec3::Zero();  // direction of the segment ending there
  std::atomic<double> pushed_mm_{0.0};     // path length handed to the servo thread
  std::atomic<uint64_t> pushed_{0};
  // Waypoints the servo thread may take: each planner step (a command, a flush) publishes all
  // the waypoints it produced at once, so virtual time never runs a cycle on part of them (the
  // cycle's braking depends on how far the known path reaches).
  std::atomic<uint64_t> released_{0};
  void release() { released_.store(pushed_.load(std::memory_order_relaxed), std::memory_order_release); }
  std::atomic<uint64_t> moves_{0};
  std::atomic<bool> waiting_{false};
  std::atomic<size_t> planner_queued_{0};

  // servo thread
  maneuver::PathWindow window_;
  maneuver::StreamServo servo_;
  maneuver::PlantState x_;
  maneuver::Vec3 w_v_ = maneuver::Vec3::Zero();  // voltages held since the last cycle
  int64_t last_ns_ = 0;
  bool started_ = false;
  std::atomic<uint64_t> popped_{0};
  // The extruder is within lead_mm of the end of the known path, or on one of its last two
  // segments: what it does next may depend on waypoints the planner has not released yet (virtual
  // time waits for them).
  std::atomic<bool> need_more_{true};  // at power-on the servo holds, waiting for waypoints
  ManeuverTelemetry telemetry_;
};

// The executor for config::Drive::dc_servo (engine/executor_factory.cpp).
Result<std::unique_ptr<CommandExecutor>> make_maneuver_executor(const config::MachineConfig& cfg);

// G-code through engine::Machine with the maneuvering executor on a VirtualClock (what `feedloop
// batch` can call for drive: dc_servo): lines are streamed into the command queue as it drains.
struct ManeuverRunSummary {
  uint64_t commands = 0;         // lines executed (comments and blanks are not sent)
  uint64_t rejected = 0;
  std::string first_error;       // first rejected line, with its location
  uint64_t moves = 0;            // final moves from the lookahead
  uint64_t segments_entered = 0; // path segments the controller followed (none skipped: = moves)
  double virtual_s = 0.0;        // machine time from start to the end of motion
  double path_time_s = 0.0;      // time spent following the path
  double path_mm = 0.0;
  double max_cross_track_mm = 0.0;
  double iae_cross_track_mm_s = 0.0;
  double max_error_mm = 0.0;
  double max_voltage_v = 0.0;
  double end_mm[3] = {0.0, 0.0, 0.0};
  bool faulted = false;
};
Result<ManeuverRunSummary> run_maneuver_virtual(const config::MachineConfig& cfg,
                                                const std::vector<std::string>& gcode_lines,
                                                double timeout_s = 600.0);

}  // namespace feedloop::engine
