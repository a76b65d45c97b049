// After a fault the machine is in error, not busy: the motion still queued will not run, and a
// status that stayed "busy" kept the print open and every host waiting.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>

#include "core/clock.hpp"
#include "engine/machine.hpp"

namespace feedloop::engine {
namespace {

// Motion queued that never finishes (as after an MCU fault), and a fault the test raises.
class StuckExecutor final : public CommandExecutor {
 public:
  Status execute(const gcode::Command&, const std::atomic<bool>&) override {
    if (fault.load()) return Error{"motion stopped: x encoder implausible"};
    return Status::Ok();
  }
  void position(double out_mm[4]) const override { out_mm[0] = out_mm[1] = out_mm[2] = out_mm[3] = 0; }
  bool motion_pending() const override { return true; }
  bool faulted() const override { return fault.load(); }
  std::atomic<bool> fault{false};
};

MachineState wait_for_state(const Machine& m, MachineState want) {
  MachineState s = m.status().state;
  for (int i = 0; i < 200 && s != want; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    s = m.status().state;
  }
  return s;
}

TEST(MachineFault, StatusLeavesBusyAfterAFault) {
  MonotonicClock clock;
  auto exec = std::make_unique<StuckExecutor>();
  StuckExecutor* e = exec.get();
  MachineOptions o;
  o.realtime_priority = 0;
  o.lock_memory = false;
  Machine m(o, clock, std::move(exec));
  ASSERT_TRUE(m.start(nullptr).ok());
  EXPECT_EQ(wait_for_state(m, MachineState::kBusy), MachineState::kBusy);
  EXPECT_FALSE(m.idle());
  e->fault.store(true);
  EXPECT_EQ(wait_for_state(m, MachineState::kError), MachineState::kError);
  EXPECT_TRUE(m.idle());  // the print can end, ownership can pass
  m.stop();
}

}  // namespace
}  // namespace feedloop::engine
