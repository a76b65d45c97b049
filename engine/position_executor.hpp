// The simplest executor: keeps the G-code position state (G90/G91, M82/M83, G92, G20/G21) and
// moves instantly. Used until the lookahead planner is wired into the machine.
#pragma once

#include "engine/machine.hpp"

namespace feedloop::engine {

class PositionExecutor final : public CommandExecutor {
 public:
  Status execute(const gcode::Command& cmd, const std::atomic<bool>& cancel) override;
  void position(double out_mm[4]) const override;

 private:
  double pos_mm_[4] = {0, 0, 0, 0};
  bool relative_xyz_ = false;
  bool relative_e_ = false;
  double unit_mm_ = 1.0;
};

}  // namespace feedloop::engine
