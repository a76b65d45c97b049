// Options shared by the model-based feedforwards (gantry and delta): servo period, preview,
// how the command reaches the motor, the weight of the preview inverse, and a uniform grid of
// the scheduling variable with its interpolation (RT-safe, no allocation).
#pragma once

#include <algorithm>  // std::clamp
#include <cmath>      // std::floor

#include "control/feedforward/preview_design.hpp"

namespace feedloop::control {

struct LpvDesignOptions {
  double period_s = 1e-3;               // servo period T
  int preview_samples = 20;             // P (lpv.preview_ms / T)
  CommandHold hold = CommandHold::linear;
  PreviewWeights weights;
};

// count points lo, lo + h, ..., hi (count >= 1; one point: a constant schedule).
struct UniformGrid {
  double lo = 0.0;
  double step = 1.0;
  int count = 1;

  static UniformGrid span(double lo, double hi, int count) {
    UniformGrid g;
    g.lo = lo;
    g.count = count < 1 ? 1 : count;
    g.step = g.count > 1 ? (hi - lo) / (g.count - 1) : 1.0;
    return g;
  }
  double at(int i) const { return lo + step * i; }
  // The cell holding x (clamped to the grid) and the weight of its upper point.
  void locate(double x, int& i, double& w) const {
    if (count == 1) {
      i = 0;
      w = 0.0;
      return;
    }
    const double s = std::clamp((x - lo) / step, 0.0, static_cast<double>(count - 1));
    i = std::min(static_cast<int>(std::floor(s)), count - 2);
    w = s - i;
  }
};

}  // namespace feedloop::control
