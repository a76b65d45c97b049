// A uniform frequency grid in Hz. The default is the delta paper's validation grid:
// 2 to 125 Hz in 0.5 Hz steps = 247 points (Sect. IV-C, Eq. 71; DESIGN.md FRF contract).
#pragma once

#include <cmath>
#include <vector>

#include "core/result.hpp"

namespace feedloop::model {

struct FrequencyGrid {
  double start_hz = 2.0;
  double stop_hz = 125.0;
  double step_hz = 0.5;

  // Number of points: start, start+step, ... up to stop (inclusive, within 1e-9 of a step).
  int size() const {
    return static_cast<int>(std::floor((stop_hz - start_hz) / step_hz + 1e-9)) + 1;
  }
  // Point k computed as start + k*step (no accumulated rounding).
  double at_hz(int k) const { return start_hz + step_hz * k; }
  std::vector<double> points_hz() const {
    std::vector<double> f(static_cast<size_t>(size()));
    for (int k = 0; k < size(); ++k) f[static_cast<size_t>(k)] = at_hz(k);
    return f;
  }
  Status validate() const {
    if (!(start_hz > 0.0) || !(step_hz > 0.0) || !(stop_hz >= start_hz) || !std::isfinite(stop_hz))
      return Error{"frequency grid needs 0 < start_hz <= stop_hz and step_hz > 0", {}};
    if (size() > 1000000) return Error{"frequency grid has more than 1e6 points", {}};
    return {};
  }
};

}  // namespace feedloop::model
