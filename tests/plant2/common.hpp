// Helpers of the second simulator's tests: a quiet axis (no friction, detent, errors or damping
// unless a test turns them on) and a sinusoid's amplitude at a known frequency.
#pragma once

#include <cmath>
#include <vector>

#include "plant2/params.hpp"

namespace feedloop::plant2::p2test {

inline Axis2Params quiet_params() {
  Axis2Params p;
  p.carriage.coulomb_n = 0.0;
  p.carriage.static_n = 0.0;
  p.carriage.viscous_n_s_m = 0.0;
  p.stepper.detent_torque_nm = 0.0;
  p.encoder.interp_amplitude_m = 0.0;
  p.encoder.resolution_m = 0.0;
  return p;
}

// Amplitude of the component of y at phase angles ph (sum over an integer number of cycles,
// mean removed): hypot of the sine and cosine projections.
inline double amplitude_at(const std::vector<double>& y, const std::vector<double>& ph) {
  double mean = 0.0;
  for (double v : y) mean += v;
  mean /= static_cast<double>(y.size());
  double s = 0.0, c = 0.0;
  for (size_t i = 0; i < y.size(); ++i) {
    s += (y[i] - mean) * std::sin(ph[i]);
    c += (y[i] - mean) * std::cos(ph[i]);
  }
  const double n = static_cast<double>(y.size());
  return 2.0 * std::hypot(s, c) / n;
}

}  // namespace feedloop::plant2::p2test
