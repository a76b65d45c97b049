// A first-order lead-lag (1 + zero s) / (1 + pole s) at sample period h by Tustin,
// s -> (2 / h) (z - 1) / (z + 1): y_k = b0 x_k + b1 x_{k-1} - a1 y_{k-1}. The motor's field lag
// (ident/axis_model.hpp, field_lag_ms) is one in identification's model, and its inverse, the
// same form with zero and pole swapped, is one in the LPV feedforward
// (control/feedforward/gantry_lpv.cpp): both take their coefficients here, so the feedforward
// inverts exactly what identification fitted.
#pragma once

#include <complex>
#include <numbers>

namespace feedloop::model {

// The motor's field lag needs c1 / k1 (the feedforward's pole) at least this long, s: with none
// Tustin puts the pole at z = -1 and the inverse rings at half the servo rate (the config and the
// feedforward refuse it, identification does not fit it).
inline constexpr double kMinFieldDampingLagS = 1e-5;

struct TustinLeadLag {
  double b0 = 1.0, b1 = 0.0, a1 = 0.0;
};

inline TustinLeadLag tustin_lead_lag(double zero_s, double pole_s, double h) {
  return {(h + 2.0 * zero_s) / (h + 2.0 * pole_s), (h - 2.0 * zero_s) / (h + 2.0 * pole_s),
          (h - 2.0 * pole_s) / (h + 2.0 * pole_s)};
}

// Its frequency response at f_hz (z = exp(j 2 pi f h)).
inline std::complex<double> tustin_lead_lag_response(double zero_s, double pole_s, double h,
                                                     double f_hz) {
  const std::complex<double> z = std::polar(1.0, 2.0 * std::numbers::pi * f_hz * h);
  const std::complex<double> s = (2.0 / h) * (z - 1.0) / (z + 1.0);
  return (1.0 + zero_s * s) / (1.0 + pole_s * s);
}

}  // namespace feedloop::model
