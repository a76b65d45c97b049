// An ideal step generator for tests and benchmarks: turns a commanded position into step pulses
// on a MotorPort. Each update(t, target) emits the steps needed to reach round(target /
// mm_per_step) over (t_prev, t], timed one of two ways:
//  - StepTiming::even (default): spread evenly with the last at t, so coarse update intervals
//    still give evenly timed pulses, and several drivers of one plant (a delta's carriages)
//    updated in turn at the same t never hand it a step earlier than one already applied;
//  - StepTiming::threshold: each step when the line from the previous target to this one crosses
//    its half-step threshold (n + 1/2), as the production step generator places them
//    (drivers/stepgen). The staircase is round() of the line, centred on it; evenly spread steps
//    lag the line by half a step on average, an offset no real driver has (in the identification's
//    recordings it biased the gantry X axis's fitted stiffness 2x low, docs/ident.md). One driver
//    per plant (or drivers updated in time order).
// (The production step generator lives in drivers/; this one exists so the simulator can be
// exercised on its own.)
#pragma once

#include <cmath>    // llround
#include <cstdint>  // int64_t

#include "drivers/device/motor_port.hpp"

namespace feedloop::sim {

enum class StepTiming { even, threshold };

class StepDriver {
 public:
  // The step counter starts at zero at position start_mm (the port's power-on position).
  StepDriver(device::MotorPort& port, double mm_per_step, double start_mm = 0.0, double t0_s = 0.0,
             StepTiming timing = StepTiming::even)
      : port_(&port),
        mm_per_step_(mm_per_step),
        start_mm_(start_mm),
        t_prev_s_(t0_s),
        timing_(timing) {}

  // RT-safe.
  void update(double t_s, double target_mm) {
    const double s1 = (target_mm - start_mm_) / mm_per_step_;  // the line's end, in steps
    const auto goal = static_cast<int64_t>(std::llround(s1));
    const int64_t n = goal - steps_;
    const int64_t count = n >= 0 ? n : -n;
    const int dir = n >= 0 ? 1 : -1;
    const double s0 = target_steps_, span = s1 - s0, dt = t_s - t_prev_s_;
    for (int64_t i = 1; i <= count; ++i) {
      // Threshold of step i: half a step beyond the count it leaves.
      const double x = static_cast<double>(steps_) + dir * (static_cast<double>(i) - 0.5);
      double f = timing_ == StepTiming::threshold && span != 0.0
                     ? (x - s0) / span
                     : static_cast<double>(i) / static_cast<double>(count);
      if (!(f > 0.0)) f = 0.0;  // a first update from a position off the step grid
      if (f > 1.0) f = 1.0;
      port_->step(t_prev_s_ + dt * f, dir);
    }
    steps_ = goal;
    target_steps_ = s1;
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
  double target_steps_ = 0.0;  // the last target, in steps from start_mm (not rounded)
  StepTiming timing_;
};

}  // namespace feedloop::sim
