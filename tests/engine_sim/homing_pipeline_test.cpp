// G28 through the endstops in the daemon's pipeline (issue 16; docs/homing.md): Machine with its
// planner and servo threads in virtual time (feedloopd --virtual-time), the MotionExecutor pausing
// its step stream while the McuBridge runs drivers::HomingSequence on each axis's MCU against the
// simulated switches (sim/endstop.hpp), then re-basing the step generators at the homed position.
// The plant has what the host's homing model lacks: the switch's trip point scatters (sigma), the
// carriage lags the motor through the belt and the rotor (a constant offset at the second touch).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "config/config.hpp"
#include "core/clock.hpp"
#include "core/rng.hpp"
#include "engine/config_mapping.hpp"
#include "engine/executor_factory.hpp"
#include "engine/machine.hpp"
#include "engine/mcu_bridge.hpp"
#include "engine/motion_executor.hpp"
#include "engine/telemetry_tap.hpp"
#include "gcode/parser.hpp"
#include "planner/kinematics.hpp"
#include "tests/common/sanitizer_stage.hpp"
#include "tests/common/servo_hold.hpp"

namespace feedloop::engine {
namespace {

// The daemon's machine on the simulated printer, in virtual time; one G-code line at a time.
struct PipelineRig {
  VirtualClock clock{1'000'000'000};
  std::shared_ptr<McuBridge> bridge;
  std::unique_ptr<Machine> machine;
  std::atomic<uint64_t> done{0};
  std::mutex mutex;
  std::string last_error;  // of the last command (protected by mutex)
  uint64_t ticket = 0;

  MotionExecutor* ex = nullptr;

  // tap: an observer of the executor (HoldBelowX below), or none.
  explicit PipelineRig(const config::MachineConfig& cfg, TelemetryTap* tap = nullptr) {
    auto stack = make_motion_stack(cfg, motion_options(cfg));
    EXPECT_TRUE(stack.ok()) << (stack.ok() ? "" : stack.error().message);
    if (!stack.ok()) return;
    bridge = stack.value().bridge;
    ex = stack.value().executor.get();
    if (tap != nullptr) ex->set_telemetry(tap);
    machine =
        std::make_unique<Machine>(machine_options(cfg), clock, std::move(stack.value().executor));
    machine->set_done_callback([this](CommandDone d) {
      {
        std::lock_guard lock(mutex);
        last_error = d.status.ok() ? "" : d.status.error().to_string();
      }
      done.fetch_add(1);
    });
    EXPECT_TRUE(machine->start().ok());
  }
  ~PipelineRig() {
    if (machine) machine->stop();
  }
  // Runs one line to its completion (virtual time runs meanwhile); its error, "" when it succeeded.
  std::string run(const std::string& line) {
    auto cmd = parse(line);
    if (!cmd.ok()) return cmd.error().message;
    return wait(submit(cmd.value()));
  }
  double seconds() const { return seconds_from_ns(clock.now_ns()) - 1.0; }
  Result<gcode::Command> parse(const std::string& line) const {
    return gcode::parse_line(line, SourceLocation{"homing.gcode", static_cast<int>(ticket) + 1, 0});
  }
  // Submits one command (or line) without waiting for it; its ticket.
  uint64_t submit(const gcode::Command& cmd) {
    while (!machine->try_submit(++ticket, cmd))
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    return ticket;
  }
  uint64_t submit(const std::string& line) {
    auto cmd = parse(line);
    EXPECT_TRUE(cmd.ok());
    return cmd.ok() ? submit(cmd.value()) : ticket;
  }
  // Waits for ticket t (and everything before it); its error, "" when it succeeded.
  std::string wait(uint64_t t) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (done.load() < t && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    if (done.load() < t) return "timeout";
    std::lock_guard lock(mutex);
    return last_error;
  }
};

config::MachineConfig homing_config(double sigma_um) {
  config::MachineConfig cfg = config::default_config();
  EXPECT_FALSE(cfg.planner.allow_moves_before_homing);
  cfg.simulator.endstops.sigma_um = sigma_um;
  cfg.servo.realtime_priority = 0;
  cfg.servo.lock_memory = false;
  return cfg;
}

struct Spread {
  double mean_um = 0.0, sd_um = 0.0;
};
Spread spread_um(const std::vector<double>& v_mm) {
  Spread s;
  for (double v : v_mm) s.mean_um += v * 1e3;
  s.mean_um /= static_cast<double>(v_mm.size());
  for (double v : v_mm) s.sd_um += (v * 1e3 - s.mean_um) * (v * 1e3 - s.mean_um);
  s.sd_um = std::sqrt(s.sd_um / static_cast<double>(v_mm.size() - 1));
  return s;
}

// N homings of X from random positions 3-40 mm away, each followed by a move there: the error of
// each homing is the true carriage position (at rest after the homing) minus the host's homed
// position. Returns the errors (mm).
std::vector<double> home_x_repeatedly(PipelineRig& rig, int n, uint64_t seed) {
  std::vector<double> err;
  Rng rng(seed);
  for (int k = 0; k < n; ++k) {
    char line[64];
    std::snprintf(line, sizeof line, "G1 X%.3f F6000", 3.0 + 37.0 * rng.uniform());
    EXPECT_EQ(rig.run(line), "");
    EXPECT_EQ(rig.run("G28 X"), "");
    const HomingReport r = rig.bridge->homing_report(0);
    EXPECT_EQ(r.count, static_cast<uint64_t>(k + 2));  // the first G28 homed every axis
    err.push_back(r.true_carriage_mm - r.homed_mm);
  }
  return err;
}

TEST(HomingPipeline, MoveBeforeG28IsRefusedThenG28HomesEveryAxisAndMovesFollow) {
  PipelineRig rig(homing_config(2.0));
  ASSERT_TRUE(rig.machine);
  const std::string refused = rig.run("G1 X10 F6000");
  EXPECT_NE(refused.find("Must home axis first (X not homed"), std::string::npos) << refused;
  EXPECT_NE(refused.find("homing.gcode:1"), std::string::npos) << refused;
  // The carriages start 2 mm from their switches (simulator.endstops.start_distance_mm).
  SimulatedPlant* plant = rig.bridge->plant();
  ASSERT_NE(plant, nullptr);
  EXPECT_NEAR(plant->carriage_mm(0), 2.0, 1e-6);
  const double t0 = rig.seconds();
  ASSERT_EQ(rig.run("G28"), "");
  const double homing_s = rig.seconds() - t0;
  const MachineStatus s = rig.machine->status();
  EXPECT_STREQ(s.homed_axes, "xyz");
  EXPECT_EQ(s.homings, 1u);
  for (int j = 0; j < 3; ++j) {
    const HomingReport r = rig.bridge->homing_report(j);
    std::printf("G28: %c homed at %.4f mm, carriage truly at %.4f mm (first touch %.4f mm)\n",
                "xyz"[j], r.homed_mm, r.true_carriage_mm, r.first_touch_mm);
    EXPECT_EQ(r.count, 1u);
    // By the steps: position_endstop plus the steps after the trigger (<= 4 samples at the second
    // touch's 10 / 5 mm/s, and a step) in the switch's direction.
    EXPECT_LE(r.steps_homed_mm, 0.0);
    EXPECT_GT(r.steps_homed_mm, -0.02);
    EXPECT_DOUBLE_EQ(s.homed_position_mm[j], r.homed_mm);
    EXPECT_DOUBLE_EQ(s.pos_mm[j], r.homed_mm);  // the interpreter continues from there
    if (j < 2) {
      // X and Y have linear encoders: the homed position is the carriage's (docs/homing.md
      // "Carriage-referenced homing"), within the switch's scatter (sigma 2 um) and the encoder.
      EXPECT_TRUE(r.encoder_referenced);
      EXPECT_NEAR(r.true_carriage_mm, r.homed_mm, 0.01);
    } else {
      // Z has none: the steps are the reference, the carriage's lag at the trigger an offset.
      EXPECT_FALSE(r.encoder_referenced);
      EXPECT_DOUBLE_EQ(r.homed_mm, r.steps_homed_mm);
      EXPECT_NEAR(r.true_carriage_mm, r.homed_mm, 0.12);
    }
    EXPECT_EQ(rig.bridge->endstop_state(j), 1);  // it stopped on its switch
  }
  // The first command also starts the MCUs (identification, 1 s of clock sync).
  std::printf("G28 of x, y, z together took %.2f s of machine time (with the MCUs' 1 s start)\n",
              homing_s);
  EXPECT_LT(homing_s, 2.5);  // the default homing stays short (carriages start near the switches)
  EXPECT_EQ(rig.bridge->timing(0).unexpected_steps, 0u);
  EXPECT_GT(rig.bridge->timing(0).homing_steps, 200u);  // 2 mm approach + 2 x 2 mm at 94 steps/mm
  // Moves now run from the homed position, closed loop on the device.
  ASSERT_EQ(rig.run("G1 X20 Y10 Z1 F6000"), "");
  ASSERT_EQ(rig.run("M400"), "");
  ASSERT_EQ(rig.run("G4 P500"), "");
  ASSERT_EQ(rig.run("M400"), "");
  std::printf("after G1 X20 Y10 Z1 at rest: carriages at %.4f %.4f %.4f mm\n",
              plant->carriage_mm(0), plant->carriage_mm(1), plant->carriage_mm(2));
  EXPECT_NEAR(plant->carriage_mm(0), 20.0, 0.01);  // no lag offset (carriage-referenced)
  EXPECT_NEAR(plant->carriage_mm(1), 10.0, 0.01);
  EXPECT_NEAR(plant->carriage_mm(2), 1.0, 0.05);  // Z: the homing's lag offset stays
  EXPECT_EQ(rig.bridge->timing(0).unexpected_steps, 0u);
  EXPECT_EQ(rig.bridge->endstop_state(0), 0);  // released
}

// Holds the servo thread at the first encoder sample of X below x_mm once armed, until release().
class HoldBelowX final : public testing::ServoHold {
 public:
  explicit HoldBelowX(double x_mm) : x_mm_(x_mm) {}
  void arm() { armed_.store(true); }
  void on_encoder_sample(const EncoderReading& r) override {
    if (armed_.load() && r.joint == 0 && r.mm < x_mm_) hold_here();
  }

 private:
  double x_mm_;
  std::atomic<bool> armed_{false};
};

// Homed, the carriage sent to X 60, then "G28 X" submitted; returns with the servo thread held
// (`hold`, armed here) at the carriage's first encoder sample below hold's x on its way to the
// switch. The G28's ticket; *t_submit its time, *homed the X homings done before it.
uint64_t g28_x_under_way(PipelineRig& rig, HoldBelowX& hold, double* t_submit, uint64_t* homed) {
  EXPECT_EQ(rig.run("G28"), "");
  *homed = rig.bridge->homing_report(0).count;
  EXPECT_EQ(rig.run("G1 X60 F6000"), "");
  EXPECT_EQ(rig.run("M400"), "");
  hold.arm();
  const uint64_t g28 = rig.submit("G28 X");
  *t_submit = rig.seconds();
  EXPECT_TRUE(hold.wait_held(60.0)) << "X never came below the hold";
  return g28;
}

// A cancel (a flush: M524, a job's cancel) while G28 runs aborts the homing on the MCUs at once:
// the G28 fails with the reason, the carriage stops short of its switch, the axis is unhomed, and
// the next G28 homes. (Before, the homing ran on to its end after the G28 had given up.)
TEST(HomingPipeline, AFlushDuringG28AbortsTheHoming) {
  HoldBelowX hold(50.0);  // well into the approach; outlives the rig (the executor's tap)
  PipelineRig rig(homing_config(2.0), &hold);
  ASSERT_TRUE(rig.machine);
  struct ReleaseFirst {  // on every way out, before the rig joins the servo thread
    HoldBelowX& h;
    ~ReleaseFirst() { h.release(); }
  } release_first{hold};
  SimulatedPlant* plant = rig.bridge->plant();
  ASSERT_NE(plant, nullptr);
  double t_submit = 0.0;
  uint64_t homings = 0;
  const uint64_t g28 = g28_x_under_way(rig, hold, &t_submit, &homings);
  ASSERT_LT(rig.done.load(), g28) << "the homing ended before the flush";
  const double x_at_flush = rig.bridge->encoder_mm(0);
  const double t_flush = rig.seconds();
  rig.machine->flush(false);
  // The servo thread runs on once the planner thread has asked it to abort the homing: it aborts
  // on its next cycle, whatever either thread's scheduling.
  const auto asked_by = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (!rig.ex->homing_abort_requested() && std::chrono::steady_clock::now() < asked_by)
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  EXPECT_TRUE(rig.ex->homing_abort_requested());
  EXPECT_EQ(rig.seconds(), t_flush);  // no virtual time passed: the servo thread is held
  hold.release();
  const std::string err = rig.wait(g28);
  const double t_done = rig.seconds();
  std::printf("flush at %.3f s into G28 X, carriage at %.2f mm; G28 ended %.3f s later: %s\n",
              t_flush - t_submit, x_at_flush, t_done - t_flush, err.c_str());
  EXPECT_NE(err.find("cancelled during homing"), std::string::npos) << err;
  EXPECT_NE(err.find("not homed"), std::string::npos) << err;
  EXPECT_LT(t_done - t_flush, 0.5);  // not the rest of the approach (60 mm)
  EXPECT_GT(x_at_flush, 5.0);
  ASSERT_EQ(rig.run("G4 P300"), "");  // the carriage has stopped, short of the switch
  const double x_rest = plant->carriage_mm(0);
  ASSERT_EQ(rig.run("G4 P300"), "");
  EXPECT_NEAR(plant->carriage_mm(0), x_rest, 0.005);
  EXPECT_GT(x_rest, 2.0);
  EXPECT_EQ(rig.bridge->endstop_state(0), 0);
  EXPECT_EQ(rig.bridge->homing_report(0).count, homings);  // no homing completed meanwhile
  EXPECT_EQ(std::string(rig.machine->status().homed_axes).find('x'), std::string::npos);
  const std::string refused = rig.run("G1 X10 F6000");
  EXPECT_NE(refused.find("Must home axis first"), std::string::npos) << refused;
  ASSERT_EQ(rig.run("G28 X"), "");
  EXPECT_EQ(rig.bridge->homing_report(0).count, homings + 1);
  EXPECT_NEAR(plant->carriage_mm(0), rig.bridge->homing_report(0).homed_mm, 0.01);
}

// The machine stopping (SIGTERM) while G28 runs: the servo thread may leave on the cycle the stop
// arrives, before it answers the homing; the planner thread must not wait for that answer (it
// waited a second of wall time, which a loaded machine stretched past the daemon's 2 s to exit).
TEST(HomingPipeline, StoppingTheMachineDuringG28DoesNotWaitForTheServo) {
  HoldBelowX hold(55.0);  // outlives the rig (the executor's tap)
  PipelineRig rig(homing_config(2.0), &hold);
  ASSERT_TRUE(rig.machine);
  struct ReleaseFirst {  // on every way out, before the rig joins the servo thread
    HoldBelowX& h;
    ~ReleaseFirst() { h.release(); }
  } release_first{hold};
  double t_submit = 0.0;
  uint64_t homings = 0;
  const uint64_t g28 = g28_x_under_way(rig, hold, &t_submit, &homings);
  ASSERT_LT(rig.done.load(), g28) << "the homing ended before the stop";
  hold.release();  // the servo thread runs the homing on; the stop arrives during it
  const auto t0 = std::chrono::steady_clock::now();
  rig.machine->stop();
  const double stop_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("Machine::stop() during G28 X returned after %.3f s of wall time\n", stop_s);
  EXPECT_LT(stop_s, 0.5);
}

// Issue 16: homing repeatability on the simulator within the endstop model's repeatability,
// through the daemon's pipeline. The homed position is the trip point on the step grid
// (q = 10.6 um on X): its spread lies within sigma +- q/2 (docs/homing.md), here measured over 20
// homings, so with the sample's own scatter (+-32 % at 2 sd for 20 samples) on top.
TEST(HomingPipeline, TwentyG28XRepeatWithinTheSwitchSigma) {
  FEEDLOOP_GCC_STAGE_ONLY("statistics over 40 homings; G28 and G28 X run here in the other tests");
  for (double sigma_um : {2.0, 20.0}) {
    PipelineRig rig(homing_config(sigma_um));
    ASSERT_TRUE(rig.machine);
    ASSERT_EQ(rig.run("G28"), "");
    const std::vector<double> err = home_x_repeatedly(rig, 20, 11);
    const Spread s = spread_um(err);
    const double q_um = 1e3 / 94.314;
    std::printf(
        "sigma %.0f um: 20 x G28 X through the pipeline: homed position spread %.2f um (1 sd), "
        "mean "
        "offset %.2f um (carriage - host); bound sigma +- q/2 = %.2f .. %.2f um\n",
        sigma_um, s.sd_um, s.mean_um, std::max(0.0, sigma_um - q_um / 2), sigma_um + q_um / 2);
    EXPECT_GE(s.sd_um, 0.68 * std::max(0.0, sigma_um - q_um / 2));
    // The mean: X has a linear encoder, so the homing refers to the carriage (docs/homing.md
    // "Carriage-referenced homing"): the carriage's lag behind the steps at the 10 mm/s second
    // touch (72 um on the thesis X axis, the mean offset when the steps alone were the reference)
    // is out of it. Nothing drifts from homing to homing.
    EXPECT_LT(std::abs(s.mean_um), 0.5 * sigma_um + 2.0);
    EXPECT_LE(s.sd_um, 1.32 * (sigma_um + 1.0));  // the switch and the encoder's count, not q
    for (double e : err) EXPECT_NEAR(e * 1e3, s.mean_um, 5.0 * (sigma_um + q_um));
  }
}

// A long stepgen.queue_ahead_ms (a busy host wants more of it) must not overflow the MCU's run
// queue while homing: its steps go as single-step runs, 4716 a second at 50 mm/s on Y, and a
// motor holds 4096 runs. With a 1 s lead the first G28 ended "step queue overflow"; the homing's
// lead is now bounded by kHomingRunBudget runs, and each phase still starts within 100 ms.
TEST(HomingPipeline, ALongQueueAheadDoesNotOverflowTheRunQueue) {
  config::MachineConfig cfg = homing_config(2.0);
  cfg.stepgen.queue_ahead_ms = 1000.0;
  PipelineRig rig(cfg);
  ASSERT_TRUE(rig.machine);
  const double t0_s = rig.seconds();
  ASSERT_EQ(rig.run("G28"), "");
  const double homing_s = rig.seconds() - t0_s;
  ASSERT_EQ(rig.run("G1 X30 Y20 F6000"), "");
  ASSERT_EQ(rig.run("G28 X Y"), "");
  const HomingReport r = rig.bridge->homing_report(1);
  std::printf(
      "queue_ahead 1000 ms: G28 took %.2f s; after two, Y homed %.4f mm, carriage at %.4f mm\n",
      homing_s, r.homed_mm, r.true_carriage_mm);
  EXPECT_EQ(r.count, 2u);
  EXPECT_LT(std::abs(r.true_carriage_mm - r.homed_mm), 0.02);
  EXPECT_LT(homing_s, 2.6);  // as with the default lead: the phases do not wait the lead
}

// Issue 16: encoder-index homing. The switch (sigma 20 um here) picks the mark; the encoder's
// index mark (every 2 mm, the AS5311's pole pair) is the reference: the homed position repeats
// within the encoder's reading (0.49 um counts, 0.3 um noise), not the switch's scatter.
TEST(HomingPipeline, EncoderIndexHomingRepeatsWithinTheEncoderNotTheSwitch) {
  FEEDLOOP_GCC_STAGE_ONLY("statistics over 20 homings");
  config::MachineConfig cfg = homing_config(20.0);
  for (auto& a : cfg.axes)
    if (a.name == "x") {
      ASSERT_TRUE(a.encoder && a.homing);
      a.encoder->index_period_mm = 2.0;
      a.homing->index = true;
    }
  PipelineRig rig(cfg);
  ASSERT_TRUE(rig.machine);
  ASSERT_EQ(rig.run("G28"), "");
  const std::vector<double> err = home_x_repeatedly(rig, 20, 11);
  const Spread s = spread_um(err);
  std::printf(
      "switch sigma 20 um, encoder index every 2 mm: 20 x G28 X: homed position spread %.2f um "
      "(1 sd), mean offset %.2f um (carriage - host; the first G28 measured the mark by the "
      "switch)\n",
      s.sd_um, s.mean_um);
  EXPECT_LT(s.sd_um, 0.7);  // the switch alone: ~20 um (TwentyG28XRepeatWithinTheSwitchSigma)
  for (double e : err) EXPECT_NEAR(e * 1e3, s.mean_um, 2.0);
  EXPECT_LT(std::abs(s.mean_um), 3.0 * 20.0);  // the first G28's switch error, within 3 sigma
  // With the mark's position in the config, the first G28 is as repeatable as the others.
  const HomingReport first = rig.bridge->homing_report(0);
  EXPECT_TRUE(std::isfinite(first.homed_mm));
}

// Issue 16: stall (sensorless) homing. X has no switch but the frame's hard stop at its
// position_endstop; the MCU trips when the encoder falls 0.5 mm behind the steps; the carriage
// is referred to by the encoder's count at the trip, then the motor backs off the stop.
TEST(HomingPipeline, StallHomingAgainstTheHardStopRepeatsAndMovesFollow) {
  FEEDLOOP_GCC_STAGE_ONLY("statistics over 20 homings");
  config::MachineConfig cfg = homing_config(20.0);
  for (auto& a : cfg.axes)
    if (a.name == "x") {
      ASSERT_TRUE(a.encoder && a.homing);
      a.homing->stall = true;
      a.homing->stall_threshold_mm = 0.5;
      a.homing->retract_dist_mm = 0.0;
    }
  PipelineRig rig(cfg);
  ASSERT_TRUE(rig.machine);
  ASSERT_EQ(rig.run("G28"), "");
  const std::vector<double> err = home_x_repeatedly(rig, 20, 11);
  const Spread s = spread_um(err);
  std::printf(
      "stall homing on X (hard stop, threshold 0.5 mm): 20 x G28 X: homed position spread %.2f um "
      "(1 sd), mean offset %.2f um (carriage - host)\n",
      s.sd_um, s.mean_um);
  EXPECT_LT(s.sd_um, 2.0);
  // The mean: the carriage at the trip is pressed into the stop by the belt's force (the
  // simulated stop's 2e5 N/m gives ~70 um): a constant, calibrated out in position_endstop_mm.
  EXPECT_LT(std::abs(s.mean_um), 100.0);
  ASSERT_EQ(rig.run("G1 X100 F6000"), "");
  ASSERT_EQ(rig.run("M400"), "");
  ASSERT_EQ(rig.run("G4 P500"), "");
  ASSERT_EQ(rig.run("M400"), "");
  EXPECT_NEAR(rig.bridge->plant()->carriage_mm(0), 100.0 + s.mean_um * 1e-3, 0.01);
  EXPECT_EQ(rig.machine->status().lost_step_events, 0u);
}

TEST(HomingPipeline, NoTriggerFailsWithKlippersMessageAndLeavesTheAxisUnhomed) {
  config::MachineConfig cfg = homing_config(2.0);
  for (auto& a : cfg.axes)
    if (a.name == "x") a.homing->max_travel_mm = 1.0;  // the switch is 2 mm away
  PipelineRig rig(cfg);
  ASSERT_TRUE(rig.machine);
  const std::string e = rig.run("G28 X");
  EXPECT_NE(e.find("homing.gcode:1"), std::string::npos) << e;
  EXPECT_NE(e.find("No trigger on x after full movement (1.000 mm)"), std::string::npos) << e;
  EXPECT_STREQ(rig.machine->status().homed_axes, "");
  EXPECT_NE(rig.run("G1 X5").find("Must home axis first"), std::string::npos);
  // The machine is not stuck: Y homes.
  EXPECT_EQ(rig.run("G28 Y"), "");
  EXPECT_STREQ(rig.machine->status().homed_axes, "y");
}

// A delta (Klipper's delta.py): G28 sends the three carriages up together, each stops on its own
// switch at the top of its tower; the per-tower position_endstop (the towers' endstop offsets)
// goes through the forward kinematics to the nozzle position the interpreter continues from.
config::MachineConfig delta_homing_config() {
  auto loaded = config::load_config_file(FEEDLOOP_SOURCE_DIR "/config/examples/delta_sim.yaml");
  EXPECT_TRUE(loaded.ok());
  config::MachineConfig cfg = loaded.value();
  cfg.planner.allow_moves_before_homing = false;
  cfg.servo.realtime_priority = 0;
  cfg.servo.lock_memory = false;
  const double endstop_mm[3] = {530.0, 530.4, 529.7};  // uneven towers: offsets of 0.4 and -0.3 mm
  for (int j = 0; j < 3; ++j) {
    config::HomingConfig h;
    h.direction = config::EndstopSide::max;
    h.position_endstop_mm = endstop_mm[j];
    h.homing_speed_mm_s = 50.0;
    h.second_homing_speed_mm_s = 10.0;
    h.retract_dist_mm = 2.0;
    h.max_travel_mm = 720.0;
    for (auto& a : cfg.axes)
      if (a.name == std::string(1, "ABC"[j])) a.homing = h;
  }
  return cfg;
}

// Encoder-index and stall homing on a delta's towers (each carriage has its encoder): 6 x G28,
// each tower's carriage (plant - host) at rest; the spread is the encoder's, not the switch's.
TEST(HomingPipeline, DeltaTowersHomeByTheEncoderIndexAndByStall) {
  FEEDLOOP_GCC_STAGE_ONLY("the delta homing runs in the GCC build (CI time under the sanitizers)");
  for (const char* how : {"index", "stall"}) {
    config::MachineConfig cfg = delta_homing_config();
    cfg.simulator.endstops.sigma_um = 20.0;
    for (auto& a : cfg.axes)
      if (a.homing && a.encoder) {
        if (std::string(how) == "index") {
          a.encoder->index_period_mm = 2.0;
          a.homing->index = true;
        } else {
          a.homing->stall = true;
          a.homing->retract_dist_mm = 0.0;
        }
      }
    PipelineRig rig(cfg);
    ASSERT_TRUE(rig.machine);
    std::array<std::vector<double>, 3> tower;
    for (int k = 0; k < 6; ++k) {
      ASSERT_EQ(rig.run("G28"), "") << how;
      ASSERT_EQ(rig.run("G4 P1000"), "");
      ASSERT_EQ(rig.run("M400"), "");
      const MachineStatus s = rig.machine->status();
      for (int j = 0; j < 3; ++j)
        tower[static_cast<size_t>(j)].push_back(rig.bridge->plant()->carriage_mm(j) -
                                                rig.bridge->homing_report(j).homed_mm);
      (void)s;
      ASSERT_EQ(rig.run("G1 X20 Y-10 Z200 F6000"), "");
      ASSERT_EQ(rig.run("M400"), "");
    }
    for (int j = 0; j < 3; ++j) {
      const Spread t = spread_um(tower[static_cast<size_t>(j)]);
      std::printf(
          "delta, %s homing, switch sigma 20 um: tower %c carriage (plant - host) mean %.1f um, "
          "spread %.2f um over 6 G28\n",
          how, "ABC"[j], t.mean_um, t.sd_um);
      // The switch alone: ~20 um. Stall: the towers stall one after the other through the
      // effector (measured 4.6-6.6 um).
      EXPECT_LT(t.sd_um, std::string(how) == "index" ? 3.0 : 10.0) << how;
    }
  }
}

TEST(HomingPipeline, DeltaTowersHomeTogetherAndTheEndstopOffsetsGiveTheNozzle) {
#ifdef FEEDLOOP_SANITIZED
  // 149 s under the sanitizers at the last landing, over its 300 s timeout since the heaters run
  // on their own MCU link: it runs in the GCC build (scripts/test.sh); the cartesian and corexy
  // homing tests run here. Open: why it became that much slower under ASan.
  GTEST_SKIP() << "the delta homing runs in the GCC build (CI time under the sanitizers)";
#endif
  const config::MachineConfig cfg = delta_homing_config();
  PipelineRig rig(cfg);
  ASSERT_TRUE(rig.machine);
  EXPECT_NE(rig.run("G1 Z200 F3000").find("Must home axis first"), std::string::npos);
  const auto kin = planner::make_kinematics(planner_config(cfg));
  std::vector<double> ez, ex, ey;
  std::array<std::vector<double>, 3> tower;  // each carriage: true height - homed height
  for (int k = 0; k < 8; ++k) {
    const double t0 = rig.seconds();
    ASSERT_EQ(rig.run(k == 0 ? "G28" : "G28 X"),
              "");  // a delta homes every tower whatever the letters
    const double took_s = rig.seconds() - t0;
    const MachineStatus s = rig.machine->status();
    EXPECT_STREQ(s.homed_axes, "xyz");
    planner::Joints q{};
    for (int j = 0; j < 3; ++j) {
      const HomingReport r = rig.bridge->homing_report(j);
      EXPECT_EQ(r.count, static_cast<uint64_t>(k + 1));
      q[static_cast<size_t>(j)] = r.homed_mm;
      tower[static_cast<size_t>(j)].push_back(r.true_carriage_mm - r.homed_mm);
      // Each motor stopped a few steps past its own switch (moving up: at or above it); the
      // carriages have encoders, so the homed position is the carriage's at rest (docs/homing.md
      // "Carriage-referenced homing"): below the steps' by the carriage's lag and sag.
      EXPECT_TRUE(r.encoder_referenced) << "tower " << j;
      EXPECT_GE(r.steps_homed_mm,
                cfg.axes[static_cast<size_t>(j)].homing->position_endstop_mm - 1e-9);
      EXPECT_LT(r.steps_homed_mm,
                cfg.axes[static_cast<size_t>(j)].homing->position_endstop_mm + 0.05);
      EXPECT_NEAR(r.homed_mm, r.steps_homed_mm, 0.2);
    }
    auto nozzle = kin->forward(q);
    ASSERT_TRUE(nozzle.ok());
    for (int i = 0; i < 3; ++i)
      EXPECT_NEAR(s.pos_mm[i], nozzle.value()[static_cast<size_t>(i)], 1e-9);
    // The ground truth at rest: the effector swings laterally after the stops (11 Hz, zeta 0.2,
    // coupled into the carriages), so the truth is read after a dwell (the device loops hold the
    // carriages where they are).
    ASSERT_EQ(rig.run("G4 P1000"), "");
    ASSERT_EQ(rig.run("M400"), "");
    for (int j = 0; j < 3; ++j)
      tower[static_cast<size_t>(j)].back() =
          rig.bridge->plant()->carriage_mm(j) - q[static_cast<size_t>(j)];
    const std::array<double, 3> truth = rig.bridge->plant()->nozzle_mm();
    std::printf("  homing %d: towers (plant - host) %.1f %.1f %.1f um\n", k, tower[0].back() * 1e3,
                tower[1].back() * 1e3, tower[2].back() * 1e3);
    if (k == 0)
      std::printf(
          "delta G28 (%.2f s): carriages homed at %.4f %.4f %.4f mm -> nozzle %.4f %.4f %.4f mm; "
          "plant's nozzle %.4f %.4f %.4f mm\n",
          took_s, q[0], q[1], q[2], s.pos_mm[0], s.pos_mm[1], s.pos_mm[2], truth[0], truth[1],
          truth[2]);
    ex.push_back(truth[0] - s.pos_mm[0]);
    ey.push_back(truth[1] - s.pos_mm[1]);
    ez.push_back(truth[2] - s.pos_mm[2]);
    EXPECT_LT(took_s, 3.0);
    ASSERT_EQ(rig.run("G1 X20 Y-10 Z200 F6000"), "");
    ASSERT_EQ(rig.run("M400"), "");
  }
  const Spread sx = spread_um(ex), sy = spread_um(ey), sz = spread_um(ez);
  std::printf(
      "delta, 8 x G28: nozzle (plant - host) mean %.1f %.1f %.1f um, spread %.2f %.2f %.2f um "
      "(at rest)\n",
      sx.mean_um, sy.mean_um, sz.mean_um, sx.sd_um, sy.sd_um, sz.sd_um);
  // The uneven towers (0.4 / -0.3 mm) move the nozzle by tenths of a mm: the forward kinematics
  // of the homed carriages puts the host where the plant's nozzle is. Referred to the carriages
  // (their encoders), the carriages' lag and sag are out of it (measured 2.1, -1.8, 1.6 um; with
  // the steps alone it was tenths of a mm): what is left is the switch's scatter and the
  // effector's own sag (the plant's rigid-body effector, not in the kinematics).
  for (double e : {sx.mean_um, sy.mean_um, sz.mean_um}) EXPECT_LT(std::abs(e), 25.0);
  // Each tower homes repeatably: its carriage's spread is the switch's scatter (sigma 2 um) and
  // the encoder's count (0.5 um), with the scatter of 8 samples on top: 2.5 (sigma + 1 um).
  // (Referred to the steps, tower A drifted by whole steps from one homing to the next, -95 to
  // -108 um; the encoder's reference took it out: measured spreads 2.9, 1.5, 4.4 um.)
  for (int j = 0; j < 3; ++j) {
    const Spread t = spread_um(tower[static_cast<size_t>(j)]);
    std::printf("delta tower %c: carriage (plant - host) mean %.1f um, spread %.2f um\n", "ABC"[j],
                t.mean_um, t.sd_um);
    EXPECT_LT(t.sd_um, 2.5 * (2.0 + 1.0));
    EXPECT_LT(std::abs(t.mean_um), 10.0);
  }
  // The moves follow from there: the nozzle reaches X20 Y-10 Z200.
  const std::array<double, 3> n = rig.bridge->plant()->nozzle_mm();
  EXPECT_NEAR(n[0], 20.0, 0.3);
  EXPECT_NEAR(n[1], -10.0, 0.3);
  EXPECT_NEAR(n[2], 200.0, 0.3);
}

}  // namespace
}  // namespace feedloop::engine
