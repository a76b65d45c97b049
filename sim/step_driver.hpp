// An ideal step generator for tests and benchmarks: turns a commanded position into step pulses
// on a MotorPort. Each update(t, target) emits the steps needed to reach round(target / mm_per_step)
// spread evenly over (t_prev, t], so coarse update intervals still give evenly timed pulses.
// (The production step generator lives in drivers/; this one exists so the simulator can be
// exercised on its own.)
#pragma once

#include <cmath>    // llround
#include <cstdint>  // int64_t

#include "drivers/device/motor_port.hpp"

namespace feedloop::sim {

class StepDriver {
 public:
  // The step counter starts at zero at position start_mm (the port's power-on position).
  StepDriver(device::MotorPort& port, double mm_per_step, double start_mm = 0.0, double t0_s = 0.0)
      : port_(&port), mm_per_step_(mm_per_step), start_mm_(start_mm), t_prev_s_(t0_s) {}

  // RT-safe.
  void update(double t_s, double target_mm) {
    const auto goal = static_cast<int64_t>(std::llround((target_mm - start_mm_) / mm_per_step_));
    const int64_t n = goal - steps_;
    const int64_t count = n >= 0 ? n : -n;
    const int dir = n >= 0 ? 1 : -1;
    for (int64_t i = 1; i <= count; ++i) {
      port_->step(t_prev_s_ + (t_s - t_prev_s_) * static_cast<double>(i) / static_cast<double>(count), dir);
    }
    steps_ = goal;
    t_prev_s_ = t_s;
  }
  int64_t steps() const { return steps_; }
  double commanded_mm() const { return start_mm_ + static_cast<double>(steps_) * mm_per_step_; }

 private:
  device::MotorPort* port_;
  double mm_per_step_;
  double start_mm_;
  double t_prev_s_;
  int64_t steps_ = 0;
};

}  // namespace feedloop::sim
