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
  // 0 for an invalid grid (see validate()).
  int size() const {
    if (!(step_hz > 0.0) || !(stop_hz >= start_hz) || !std::isfinite(stop_hz - start_hz)) return 0;
    const double n = std::floor((stop_hz - start_hz) / step_hz + 1e-9) + 1.0;
    return n > 2e9 ? 0 : static_cast<int>(n);
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
    if (size() == 0 || size() > 1000000) return Error{"frequency grid must have 1 to 1e6 points", {}};
    return {};
  }
};

}  // namespace feedloop::model
