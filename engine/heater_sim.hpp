// First-order thermal model of a heater under bang-bang-free ideal control, for the simulated
// printer: temperature approaches the target at a limited slew rate and settles exponentially.
// Not real-time code; updated by the planner thread.
#pragma once

#include <algorithm>
#include <cmath>

namespace feedloop::engine {

struct HeaterSim {
  double temp_c = 21.0;
  double target_c = 0.0;
  double ambient_c = 21.0;
  double max_slew_c_s = 40.0;   // heating rate limit of the simulated heater
  double cool_tau_s = 60.0;     // cooling time constant with the heater off

  void advance(double dt_s) {
    if (target_c > 0.0) {
      const double step = max_slew_c_s * dt_s;
      temp_c = temp_c < target_c ? std::min(target_c, temp_c + step) : std::max(target_c, temp_c - step);
    } else {
      temp_c = ambient_c + (temp_c - ambient_c) * std::exp(-dt_s / cool_tau_s);
    }
  }
  // Marlin's M109/M190 "reached" test: within 1 C of a non-zero target.
  bool at_target() const { return target_c <= 0.0 || std::fabs(temp_c - target_c) <= 1.0; }
};

}  // namespace feedloop::engine
