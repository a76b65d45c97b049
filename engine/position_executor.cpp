#include "engine/position_executor.hpp"

namespace feedloop::engine {

Status PositionExecutor::execute(const gcode::Command& cmd, const std::atomic<bool>& /*cancel*/) {
  static constexpr char kAxes[4] = {'X', 'Y', 'Z', 'E'};
  if (cmd.letter == 'G') {
    switch (cmd.code) {
      case 0: case 1: case 2: case 3:
        for (int i = 0; i < 4; ++i) {
          if (!cmd.has(kAxes[i])) continue;
          const double v = cmd.get(kAxes[i]) * unit_mm_;
          const bool rel = i == 3 ? relative_e_ : relative_xyz_;
          pos_mm_[i] = rel ? pos_mm_[i] + v : v;
        }
        break;
      case 20: unit_mm_ = 25.4; break;
      case 21: unit_mm_ = 1.0; break;
      case 28: pos_mm_[0] = pos_mm_[1] = pos_mm_[2] = 0.0; break;
      case 90: relative_xyz_ = false; relative_e_ = false; break;
      case 91: relative_xyz_ = true; relative_e_ = true; break;
      case 92:
        for (int i = 0; i < 4; ++i)
          if (cmd.has(kAxes[i])) pos_mm_[i] = cmd.get(kAxes[i]) * unit_mm_;
        break;
      default: break;
    }
  } else if (cmd.letter == 'M') {
    if (cmd.code == 82) relative_e_ = false;
    if (cmd.code == 83) relative_e_ = true;
  }
  return Status::Ok();
}

void PositionExecutor::position(double out_mm[4]) const {
  for (int i = 0; i < 4; ++i) out_mm[i] = pos_mm_[i];
}

}  // namespace feedloop::engine
