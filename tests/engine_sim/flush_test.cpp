// Cancel at once (issue 16, docs/jobs.md "Cancel"): engine::Machine::flush on the daemon's
// pipeline (planner and servo threads, virtual time) with the simulated printer and its device PI
// loops. The queued commands are dropped, the heaters are off at once, the planned motion slows to
// a stop along the path at the deceleration the limits allow (v^2 / 2a after the samples the MCUs
// already hold), no step is lost, and the machine goes on from where it stopped, usable at once
// (no latch): the host's position is the steps'.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "config/config.hpp"
#include "core/clock.hpp"
#include "engine/config_mapping.hpp"
#include "engine/executor_factory.hpp"
#include "engine/machine.hpp"
#include "engine/mcu_bridge.hpp"
#include "engine/motion_executor.hpp"
#include "engine/telemetry_tap.hpp"
#include "engine/thermal_config.hpp"
#include "gcode/parser.hpp"
#include "tests/common/servo_hold.hpp"

namespace feedloop::engine {
namespace {

config::MachineConfig flush_config() {
  config::MachineConfig cfg = config::default_config();
  cfg.servo.realtime_priority = 0;
  cfg.servo.lock_memory = false;
  return cfg;
}

// The daemon's machine on the simulated printer in virtual time, with its heaters.
struct FlushRig {
  config::MachineConfig cfg;
  VirtualClock clock{1'000'000'000};
  std::shared_ptr<McuBridge> bridge;
  MotionExecutor* ex = nullptr;
  std::unique_ptr<Machine> machine;
  std::mutex mutex;
  std::vector<std::string> errors;  // by ticket - 1 ("" ok)
  std::vector<double> done_at_s;    // by ticket - 1: machine time the line completed
  std::atomic<uint64_t> done{0};
  uint64_t ticket = 0;

  // tap: an observer of the executor (HoldPastX below), or none.
  explicit FlushRig(const config::MachineConfig& c, TelemetryTap* tap = nullptr) : cfg(c) {
    auto stack = make_motion_stack(cfg, motion_options(cfg));
    EXPECT_TRUE(stack.ok()) << (stack.ok() ? "" : stack.error().message);
    if (!stack.ok()) return;
    bridge = stack.value().bridge;
    ex = stack.value().executor.get();
    if (tap != nullptr) ex->set_telemetry(tap);
    machine =
        std::make_unique<Machine>(machine_options(cfg), clock, std::move(stack.value().executor));
    auto thermal = make_thermal_loop(cfg);
    EXPECT_TRUE(thermal.ok());
    if (thermal.ok()) machine->set_thermal(std::move(thermal.value()));
    errors.reserve(100000);
    done_at_s.reserve(100000);
    machine->set_done_callback([this](CommandDone d) {
      {
        std::lock_guard lock(mutex);
        if (d.ticket >= 1 && d.ticket <= errors.size())
          errors[d.ticket - 1] = d.status.ok() ? "" : d.status.error().to_string();
        if (d.ticket >= 1 && d.ticket <= done_at_s.size()) done_at_s[d.ticket - 1] = now_s();
      }
      done.fetch_add(1);
    });
    EXPECT_TRUE(machine->start().ok());
  }
  ~FlushRig() {
    if (machine) machine->stop();
  }
  // Queues one line (waits while the machine's queue is full). False: it does not parse.
  bool submit(const std::string& line) {
    auto cmd = gcode::parse_line(line, SourceLocation{"flush.gcode", static_cast<int>(ticket) + 1, 0});
    if (!cmd.ok() || cmd.value().empty()) return false;
    {
      std::lock_guard lock(mutex);
      errors.emplace_back("pending");
      done_at_s.push_back(-1.0);
    }
    ++ticket;
    while (!machine->try_submit(ticket, cmd.value()))
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    return true;
  }
  // Runs one line to its completion; its error ("" when it succeeded).
  std::string run(const std::string& line) {
    if (!submit(line)) return "does not parse: " + line;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (done.load() < ticket && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    if (done.load() < ticket) {
      const MachineStatus s = machine->status();
      std::printf("timeout on '%s': machine time %.3f s, state %s, homing %d, encoders %.3f %.3f %.3f\n",
                  line.c_str(), now_s(), to_string(s.state), s.homing ? 1 : 0, s.encoder_mm[0],
                  s.encoder_mm[1], s.encoder_mm[2]);
    }
    std::lock_guard lock(mutex);
    return errors[ticket - 1];
  }
  bool wait_idle(int timeout_s = 120) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(timeout_s);
    while (!machine->idle() && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::microseconds(500));
    return machine->idle();
  }
  double now_s() const { return seconds_from_ns(clock.now_ns()); }
  double spm(int j) const { return steps_per_mm(cfg)[static_cast<size_t>(j)]; }
  // Encoder minus steps (mm) per XY joint: constant as long as no step is lost.
  std::array<double, 2> encoder_less_steps(const MachineStatus& s) const {
    return {s.encoder_mm[0] - static_cast<double>(s.step_count[0]) / spm(0),
            s.encoder_mm[1] - static_cast<double>(s.step_count[1]) / spm(1)};
  }
};

// Holds the servo thread at its first sample with the X encoder past x_mm (the cruise past X 80
// is ~0.95 s of virtual time), until release().
class HoldPastX final : public testing::ServoHold {
 public:
  explicit HoldPastX(double x_mm) : x_mm_(x_mm) {}
  void on_servo_sample(const ServoSample& s) override {
    if (s.encoder_mm[0] > x_mm_) hold_here();
  }

 private:
  double x_mm_;
};

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// What every flush must leave: the heaters off at once, the stop within v^2/2a along the path, no
// lost step, the host's position on the steps, the machine usable (G28 and a move after).
void check_stop(FlushRig& rig, const MachineStatus& before, double request_s,
                const std::array<double, 2>& enc_less_steps_at_rest, const char* what) {
  const MotionExecutor::StopFigures f = rig.ex->last_stop();
  const MachineStatus s = rig.machine->status();
  const double period_s = 1.0 / rig.cfg.servo.rate_hz;
  const double lead_s = rig.cfg.stepgen.queue_ahead_ms * 1e-3 + 0.035;  // the device loop's lead
  const double bound_mm = f.speed_mm_s * f.speed_mm_s / (2.0 * f.decel_mm_s2);
  std::printf(
      "%s: stop from %.1f mm/s at %.0f mm/s^2: %.3f mm along the path (v^2/2a = %.3f mm) in "
      "%.1f ms, begun %.1f ms after the request (taken by the servo thread after %.1f ms; then the "
      "samples the MCUs held), %llu planned moves and %llu queued commands dropped\n",
      what, f.speed_mm_s, f.decel_mm_s2, f.path_mm, bound_mm, (f.rest_s - f.begin_s) * 1e3,
      (f.begin_s - request_s) * 1e3, (f.request_s - request_s) * 1e3, static_cast<unsigned long long>(f.moves_dropped),
      static_cast<unsigned long long>(s.commands_flushed - before.commands_flushed));
  EXPECT_TRUE(f.warped);
  EXPECT_GT(f.decel_mm_s2, 0.0);
  // Along the path: at most v^2/2a, plus the one sample the cap crosses zero in.
  EXPECT_LE(f.path_mm, bound_mm + f.speed_mm_s * period_s + 1e-6);
  EXPECT_LE(f.rest_s - f.begin_s, f.speed_mm_s / f.decel_mm_s2 + 2.0 * period_s + 1e-9);
  // The servo thread takes the request once the planner thread has left the command it ran (in
  // virtual time the servo runs on meanwhile), then slows the plan from the first sample the MCUs
  // do not hold yet.
  // How soon it is taken is the planner thread's scheduling against a servo thread free-running in
  // virtual time (7 ms here when idle): bounded loosely, so a loaded CI machine does not fail it.
  EXPECT_LE(f.request_s - request_s, 0.25);
  EXPECT_LE(f.begin_s - f.request_s, lead_s + 3.0 * period_s);
  EXPECT_GT(f.moves_dropped, 0u);
  EXPECT_EQ(s.commands_rejected, before.commands_rejected);
  EXPECT_EQ(s.state, MachineState::kIdle);
  EXPECT_STREQ(s.homed_axes, "xyz");  // no homing lost, no latch
  // No lost step: the encoders against the steps as at the rest before the print.
  EXPECT_EQ(s.lost_step_events, before.lost_step_events);
  for (int j = 0; j < 2; ++j) {
    EXPECT_EQ(rig.bridge->plant()->lost_full_steps(j), 0) << "joint " << j;
    const double d = rig.encoder_less_steps(s)[static_cast<size_t>(j)] -
                     enc_less_steps_at_rest[static_cast<size_t>(j)];
    std::printf("%s: joint %c encoder - steps moved %.2f um over the print and the stop\n", what,
                "xy"[j], d * 1e3);
    // A lost full step moves it by 16 microsteps (170 um); between two rests it moves within the
    // band friction and the stepper's torque curve leave the carriage in, which depends on the
    // arrival (up to 8.3 um measured in the Return test; a sanitizer run saw 10.68 um here, just
    // over one microstep): two microsteps.
    EXPECT_LE(std::fabs(d), 2.0 / rig.spm(j)) << "joint " << j;
  }
  // The host goes on from the rest point: its position is the steps' (no drift), and the rest
  // point the stop reported.
  for (int j = 0; j < 3; ++j) {
    EXPECT_NEAR(s.pos_mm[j] * rig.spm(j), static_cast<double>(s.step_count[j]), 0.5 + 1e-6)
        << "axis " << j;
    EXPECT_NEAR(s.pos_mm[j], f.position_mm[j], 1e-9) << "axis " << j;
  }
}

// After a flush the machine takes moves and G28 at once; positions stay on the steps.
void check_usable(FlushRig& rig) {
  ASSERT_EQ(rig.run("G1 X100 Y100 F6000"), "");
  ASSERT_EQ(rig.run("M400"), "");
  ASSERT_TRUE(rig.wait_idle());
  MachineStatus s = rig.machine->status();
  EXPECT_NEAR(s.pos_mm[0], 100.0, 1e-9);
  EXPECT_NEAR(s.pos_mm[1], 100.0, 1e-9);
  for (int j = 0; j < 2; ++j)
    EXPECT_NEAR(static_cast<double>(s.step_count[j]), 100.0 * rig.spm(j), 0.5 + 1e-6);
  EXPECT_NEAR(rig.bridge->plant()->carriage_mm(0), 100.0, 0.12);
  EXPECT_NEAR(rig.bridge->plant()->carriage_mm(1), 100.0, 0.12);
  ASSERT_EQ(rig.run("G28"), "");
  s = rig.machine->status();
  EXPECT_STREQ(s.homed_axes, "xyz");
  EXPECT_EQ(s.lost_step_events, 0u);
}

TEST(Flush, AtRestWithNothingQueuedChangesNothingButTheHeaters) {
  FlushRig rig(flush_config());
  ASSERT_TRUE(rig.machine);
  ASSERT_EQ(rig.run("G28"), "");
  ASSERT_EQ(rig.run("G1 X30 Y40 Z5 F6000"), "");
  ASSERT_EQ(rig.run("M104 S200"), "");
  ASSERT_TRUE(rig.wait_idle());
  const MachineStatus before = rig.machine->status();
  EXPECT_DOUBLE_EQ(before.hotend_target_c, 200.0);
  rig.machine->flush(true);
  EXPECT_DOUBLE_EQ(rig.machine->status().hotend_target_c, 0.0);  // on the calling thread
  ASSERT_TRUE(rig.wait_idle(10));
  const MachineStatus s = rig.machine->status();
  EXPECT_EQ(s.flushes, 1u);
  EXPECT_EQ(s.commands_flushed, 0u);
  for (int i = 0; i < 4; ++i) EXPECT_DOUBLE_EQ(s.pos_mm[i], before.pos_mm[i]);
  for (int j = 0; j < 4; ++j) EXPECT_EQ(s.step_count[j], before.step_count[j]);
  EXPECT_EQ(rig.ex->last_stop().moves_dropped, 0u);
  check_usable(rig);
}

// A 180 x 130 mm travel at the planner's 150 mm/s, cancelled while it cruises.
TEST(Flush, ATravelAtFullSpeedStopsWithinVSquaredOverTwoAAlongItsLine) {
  HoldPastX hold(80.0);  // outlives the rig (the executor's tap)
  FlushRig rig(flush_config(), &hold);
  struct ReleaseFirst {  // on every way out, before the rig joins the servo thread
    HoldPastX& h;
    ~ReleaseFirst() { h.release(); }
  } release_first{hold};
  ASSERT_TRUE(rig.machine);
  ASSERT_EQ(rig.run("G28"), "");
  ASSERT_EQ(rig.run("G1 X20 Y20 Z5 F6000"), "");
  ASSERT_EQ(rig.run("M140 S60"), "");
  ASSERT_EQ(rig.run("M104 S215"), "");
  ASSERT_EQ(rig.run("M400"), "");
  ASSERT_TRUE(rig.wait_idle());
  const MachineStatus before = rig.machine->status();
  const std::array<double, 2> at_rest = rig.encoder_less_steps(before);
  ASSERT_TRUE(rig.submit("G1 X200 Y150 F9000"));
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(rig.submit(i % 2 == 0 ? "G1 X20 Y20 F9000" : "G1 X200 Y150 F9000"));
  // Cruising: the servo thread held at the encoder past X 80 (the cruise at 150 mm/s spans
  // X 23..197), the flush requested there.
  ASSERT_TRUE(hold.wait_held(60.0));
  const double request_s = rig.now_s();
  rig.machine->flush(true);
  const MachineStatus right_after = rig.machine->status();
  EXPECT_DOUBLE_EQ(right_after.hotend_target_c, 0.0);
  EXPECT_DOUBLE_EQ(right_after.bed_target_c, 0.0);
  // The servo thread runs on once the planner thread has handed it the stop, so the request is
  // taken at the next cycle whatever either thread's scheduling (free-running, virtual time ran
  // on for as long as the planner thread took to get there: up to 0.25 s allowed before).
  const auto handed_by = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (!rig.ex->stop_waits_for_servo() && std::chrono::steady_clock::now() < handed_by)
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  EXPECT_TRUE(rig.ex->stop_waits_for_servo());
  const double heaters_off_ms = (rig.now_s() - request_s) * 1e3;
  EXPECT_EQ(heaters_off_ms, 0.0);  // no virtual time passed: the servo thread is held
  hold.release();
  ASSERT_TRUE(rig.wait_idle());
  const double idle_s = rig.now_s() - request_s;
  const MotionExecutor::StopFigures f = rig.ex->last_stop();
  std::printf("travel: heaters off %.2f ms after the request; the machine idle %.0f ms after it\n",
              heaters_off_ms, idle_s * 1e3);
  check_stop(rig, before, request_s, at_rest, "travel");
  EXPECT_LE(f.request_s - request_s,
            1.0 / rig.cfg.servo.rate_hz + 1e-9);  // taken at the next cycle
  EXPECT_NEAR(f.speed_mm_s, 150.0, 1e-6);  // cruising
  EXPECT_NEAR(f.decel_mm_s2, rig.cfg.planner.max_accel_mm_s2, 1e-9);
  // On the travel's line, short of its end, and the carriage there.
  const double t = (f.position_mm[0] - 20.0) / 180.0;
  EXPECT_GT(t, 0.3);
  EXPECT_LT(t, 0.95);
  EXPECT_NEAR(f.position_mm[1], 20.0 + 130.0 * t, 1e-6);
  EXPECT_NEAR(rig.bridge->plant()->carriage_mm(0), f.position_mm[0], 0.12);
  EXPECT_NEAR(rig.bridge->plant()->carriage_mm(1), f.position_mm[1], 0.12);
  // The five queued travels after it never ran: dropped from the machine's queue, or planned and
  // dropped as moves.
  EXPECT_EQ(rig.machine->status().commands_flushed - before.commands_flushed +
                rig.ex->last_stop().moves_dropped,
            5u);
  check_usable(rig);
}

// The middle of the benchy (the job's use): printing moves, retracts and travels queued as a file
// streams them, cancelled while the queue is full.
TEST(Flush, InTheMiddleOfTheBenchy) {
  const std::string src = std::string(FEEDLOOP_SHARED_DIR) + "/gcode/benchy_cartesian.gcode";
  if (!std::filesystem::exists(src)) GTEST_SKIP() << "the public G-code corpus is not at " << src;
  const std::string text = read_text(src);
  // From the first "G92 E0" after the middle byte (absolute E restarts there), at its layer's Z.
  const size_t from = text.find("\nG92 E0", text.size() / 2) + 1;
  const size_t z_at = text.rfind("\nG1 Z", from);
  ASSERT_NE(z_at, std::string::npos);
  const double z_mm = std::stod(text.substr(z_at + 5, 12));
  FlushRig rig(flush_config());
  ASSERT_TRUE(rig.machine);
  ASSERT_EQ(rig.run("G28"), "");
  ASSERT_EQ(rig.run("M140 S60"), "");
  ASSERT_EQ(rig.run("M104 S215"), "");
  ASSERT_EQ(rig.run("M302 P1"), "");  // extrude while it heats: the flush is what is tested
  ASSERT_EQ(rig.run("G90"), "");
  ASSERT_EQ(rig.run("M82"), "");
  char z_line[64];
  std::snprintf(z_line, sizeof z_line, "G1 Z%.3f F600", z_mm);
  ASSERT_EQ(rig.run(z_line), "");
  ASSERT_EQ(rig.run("M400"), "");
  ASSERT_TRUE(rig.wait_idle());
  const MachineStatus before = rig.machine->status();
  const std::array<double, 2> at_rest = rig.encoder_less_steps(before);
  // Stream 400 lines of the file, then cancel with the queue full, the carriage printing.
  std::istringstream in(text.substr(from));
  uint64_t submitted = 0;
  for (std::string line; submitted < 400 && std::getline(in, line);)
    if (rig.submit(line)) ++submitted;
  ASSERT_EQ(submitted, 400u);
  const uint64_t executed_before = rig.machine->status().commands_executed;
  const double request_s = rig.now_s();
  rig.machine->flush(true);
  const MachineStatus right_after = rig.machine->status();
  EXPECT_DOUBLE_EQ(right_after.hotend_target_c, 0.0);
  EXPECT_DOUBLE_EQ(right_after.bed_target_c, 0.0);
  const double heaters_off_ms = (rig.now_s() - request_s) * 1e3;  // printed (see the travel)
  ASSERT_TRUE(rig.wait_idle());
  const double idle_s = rig.now_s() - request_s;
  std::printf(
      "benchy from byte %zu (Z %.2f): cancelled after %llu of 400 lines executed, queue %u; "
      "heaters off %.2f ms after the request, the machine idle %.0f ms after it\n",
      from, z_mm, static_cast<unsigned long long>(executed_before - before.commands_executed),
      right_after.queue_depth, heaters_off_ms, idle_s * 1e3);
  EXPECT_GT(rig.machine->status().commands_flushed, 30u);  // the queue (64) was nearly full
  check_stop(rig, before, request_s, at_rest, "benchy");
  const MotionExecutor::StopFigures f = rig.ex->last_stop();
  EXPECT_NEAR(rig.bridge->plant()->carriage_mm(0), f.position_mm[0], 0.12);
  EXPECT_NEAR(rig.bridge->plant()->carriage_mm(1), f.position_mm[1], 0.12);
  // Idle once the command reached its rest point and the loop's hold after it is over (0.8 s
  // with the sub-step trim), plus a few periods. The rest point itself comes after the servo
  // thread took the request (up to a few tens of ms in virtual time: once 50 ms, which a bound
  // of a fixed 0.135 s lead + v/a + hold + 0.05 s missed by 2 ms), the lead and the stop, which
  // check_stop bounds.
  EXPECT_LE(idle_s, (f.rest_s - request_s) + motion_options(rig.cfg).control_settle_s + 0.05);
  check_usable(rig);
}

}  // namespace
}  // namespace feedloop::engine

namespace feedloop::engine {
namespace {

// Marlin's G4 waits also when nothing moves, and an M400 after it waits for its end: the pause's
// settle dwell (docs/jobs.md) relies on both. Before, a G4 on a machine at rest took no time and a
// G4 after motion only shifted the plan's clock (the M400 after it returned at the motion's end).
TEST(Dwell, AG4OnAMachineAtRestTakesItsTimeOnTheMachineClock) {
  FlushRig rig(flush_config());
  ASSERT_TRUE(rig.machine);
  ASSERT_EQ(rig.run("G28"), "");
  ASSERT_EQ(rig.run("M400"), "");
  ASSERT_TRUE(rig.wait_idle());
  for (double dwell_s : {0.05, 0.7, 2.0}) {
    const double t0 = rig.now_s();
    ASSERT_EQ(rig.run("G4 P" + std::to_string(static_cast<int>(dwell_s * 1000))), "");
    const double took_s = rig.now_s() - t0;
    std::printf("G4 P%.0f at rest: %.3f s of machine time\n", dwell_s * 1e3, took_s);
    EXPECT_GE(took_s, dwell_s - 1e-6);
    EXPECT_LT(took_s, dwell_s + 0.03);
  }
}

TEST(Dwell, AG4RightAfterAMoveHoldsTheMachineAndTheM400AfterItWaitsForItsEnd) {
  FlushRig rig(flush_config());
  ASSERT_TRUE(rig.machine);
  ASSERT_EQ(rig.run("G28"), "");
  ASSERT_EQ(rig.run("G1 X20 Y20 F6000"), "");
  ASSERT_EQ(rig.run("M400"), "");
  ASSERT_TRUE(rig.wait_idle());
  // The same move there and back, without and with a dwell between the move and the M400, each
  // timed on the machine's clock from the move's acceptance (the planner holds it, and the clock,
  // until the G4 or the M400 releases it) to the M400's completion. Not from the submission: while
  // the machine is at rest, virtual time runs on until the machine thread takes the line, by as
  // much as the test thread is slow (under the sanitizers 0.09 s).
  auto timed = [&](const std::string& move, bool dwell) {
    EXPECT_TRUE(rig.submit(move));
    const uint64_t move_ticket = rig.ticket;
    if (dwell) {
      EXPECT_TRUE(rig.submit("G4 P1000"));
    }
    EXPECT_EQ(rig.run("M400"), "");
    double took_s = 0.0;
    {
      std::lock_guard lock(rig.mutex);
      took_s = rig.done_at_s[rig.ticket - 1] - rig.done_at_s[move_ticket - 1];
    }
    for (uint64_t t = 1; t <= rig.ticket; ++t) {
      std::lock_guard lock(rig.mutex);
      EXPECT_EQ(rig.errors[t - 1], "") << "line " << t;
    }
    EXPECT_TRUE(rig.wait_idle());
    return took_s;
  };
  // The least of three of each: a busy test machine can only add time (the virtual clock runs on
  // while a thread that would release the move waits for a core; 0.25 s seen under load 5).
  double plain_s = 1e9, dwell_s = 1e9;
  for (int rep = 0; rep < 3; ++rep) {
    plain_s = std::min(plain_s, timed("G1 X120 Y60 F6000", false));
    (void)timed("G1 X20 Y20 F6000", false);
    dwell_s = std::min(dwell_s, timed("G1 X120 Y60 F6000", true));
    (void)timed("G1 X20 Y20 F6000", false);
  }
  std::printf("move then M400: %.3f s; move, G4 P1000, M400: %.3f s of machine time\n", plain_s,
              dwell_s);
  // (Each figure varies by some 30 ms from run to run: where the motion starts on the servo grid
  // and the device loops' lead; the old G4 gave a difference of 0.)
  EXPECT_NEAR(dwell_s - plain_s, 1.0, 0.06);
  const MachineStatus s = rig.machine->status();
  EXPECT_NEAR(s.pos_mm[0], 20.0, 1e-9);
  EXPECT_EQ(s.lost_step_events, 0u);
}

// M18/M84 switch the drivers off (Marlin's finish_and_disable): the simulated motors lose their
// holding torque, the axes must be homed again, and G28 switches them on first. (X Y Z: the
// simulated extruder's motor has no enable.)
TEST(MotorsOff, M84SwitchesTheDriversOffAndG28OnAgain) {
  FlushRig rig(flush_config());
  ASSERT_TRUE(rig.machine);
  SimulatedPlant* plant = rig.bridge->plant();
  ASSERT_NE(plant, nullptr);
  ASSERT_EQ(rig.run("G28"), "");
  ASSERT_EQ(rig.run("G1 X50 Y50 F6000"), "");
  for (int j = 0; j < 3; ++j) EXPECT_TRUE(plant->motor_enabled(j)) << j;
  ASSERT_EQ(rig.run("M84"), "");  // after the move has ended
  EXPECT_NEAR(rig.machine->status().pos_mm[0], 50.0, 1e-9);
  for (int j = 0; j < 3; ++j) EXPECT_FALSE(plant->motor_enabled(j)) << j;
  EXPECT_NE(rig.run("G1 X10 F6000").find("Must home axis first"), std::string::npos);
  ASSERT_EQ(rig.run("G28"), "");
  for (int j = 0; j < 3; ++j) EXPECT_TRUE(plant->motor_enabled(j)) << j;
  ASSERT_EQ(rig.run("G1 X60 Y40 F6000"), "");
  ASSERT_EQ(rig.run("M400"), "");
  // One axis: only its driver (one MCU per joint on the default printer); S alone changes nothing.
  ASSERT_EQ(rig.run("M84 S60"), "");
  for (int j = 0; j < 3; ++j) EXPECT_TRUE(plant->motor_enabled(j)) << j;
  ASSERT_EQ(rig.run("M18 X"), "");
  EXPECT_FALSE(plant->motor_enabled(0));
  EXPECT_TRUE(plant->motor_enabled(1));
  EXPECT_EQ(std::string(rig.machine->status().homed_axes).find('x'), std::string::npos);
  EXPECT_NE(std::string(rig.machine->status().homed_axes).find('y'), std::string::npos);
  ASSERT_EQ(rig.run("G1 Y60 F6000"), "");  // Y still homed: it moves, and switches X on again
  ASSERT_EQ(rig.run("M400"), "");
  EXPECT_TRUE(plant->motor_enabled(0));
  EXPECT_EQ(rig.machine->status().lost_step_events, 0u);
}

// Issue 16's "return within one encoder count" (docs/jobs.md "The return"): the same rest point
// (same step count) reached again along different ways; the encoder at rest each time against
// the first arrival's, in counts (0.49 um). A pause's return cannot copy the way the print
// arrived (the park is elsewhere), so this measures what the arrival costs. With the device
// loop's sub-step trim (control.sub_step_trim, on by default) the loop holds the encoder within
// a count of r whatever the arrival; in whole steps it was up to 17 counts (half a 10.6 um step).
TEST(Return, EveryArrivalRestsWithinOneEncoderCount) {
  FlushRig rig(flush_config());
  ASSERT_TRUE(rig.machine);
  ASSERT_EQ(rig.run("G28"), "");
  const double count_mm = 0.49e-3;
  auto settle_and_read = [&](MachineStatus* out) {
    EXPECT_EQ(rig.run("M400"), "");
    EXPECT_EQ(rig.run("G4 P500"), "");
    EXPECT_EQ(rig.run("M400"), "");
    EXPECT_TRUE(rig.wait_idle());
    *out = rig.machine->status();
  };
  // The reference arrival: from (10, 10) at 100 mm/s, 3000 mm/s^2.
  ASSERT_EQ(rig.run("G1 X10 Y10 F6000"), "");
  ASSERT_EQ(rig.run("G1 X50 Y50 F6000"), "");
  MachineStatus ref;
  settle_and_read(&ref);
  struct Way {
    const char* name;
    std::vector<std::string> lines;
  };
  const std::vector<Way> ways = {
      {"the same final move again (from elsewhere, then from (10, 10) at 100 mm/s)",
       {"G1 X120 Y80 F6000", "G1 X10 Y10 F6000", "G1 X50 Y50 F6000"}},
      {"the same final move, a third time", {"G1 X20 Y140 F6000", "G1 X10 Y10 F6000", "G1 X50 Y50 F6000"}},
      {"the same direction at 20 mm/s", {"G1 X10 Y10 F6000", "G1 X50 Y50 F1200"}},
      {"the opposite direction at 100 mm/s", {"G1 X90 Y90 F6000", "G1 X50 Y50 F6000"}},
      {"along X only, from X 10", {"G1 X10 Y50 F6000", "G1 X50 Y50 F6000"}},
      {"a short 1 mm approach in the reference direction",
       {"G1 X100 Y30 F6000", "G1 X49.293 Y49.293 F6000", "G1 X50 Y50 F6000"}},
  };
  double same_worst = 0.0;
  for (size_t k = 0; k < ways.size(); ++k) {
    for (const std::string& l : ways[k].lines) ASSERT_EQ(rig.run(l), "");
    MachineStatus s;
    settle_and_read(&s);
    double counts[2];
    for (int j = 0; j < 2; ++j) {
      EXPECT_EQ(s.step_count[j], ref.step_count[j]) << ways[k].name;
      counts[j] = (s.encoder_mm[j] - ref.encoder_mm[j]) / count_mm;
    }
    std::printf("return %zu, %s: encoder X %+.1f counts, Y %+.1f counts against the first arrival "
                "(same step count)\n",
                k, ways[k].name, counts[0], counts[1]);
    for (int j = 0; j < 2; ++j) {
      same_worst = std::max(same_worst, std::fabs(counts[j]));
      EXPECT_LE(std::fabs(counts[j]), 1.0 + 1e-9) << ways[k].name << " axis " << j;
    }
  }
  std::printf("every way: worst %.1f counts\n", same_worst);
  EXPECT_EQ(rig.machine->status().lost_step_events, 0u);
}

}  // namespace
}  // namespace feedloop::engine
