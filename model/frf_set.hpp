// A set of 3x3 frequency response matrices of a delta printer on a frequency grid:
// h[k](i, j) is the response of output carriage i to input carriage j (A, B, C = 0, 1, 2) at
// freq_hz[k]. This is the in-memory form of the predicted-FRF CSV contract (DESIGN.md).
#pragma once

#include <complex>
#include <vector>

#include <Eigen/Dense>

namespace feedloop::model {

struct FrfSet {
  std::vector<double> freq_hz;
  std::vector<Eigen::Matrix3cd> h;

  int size() const { return static_cast<int>(freq_hz.size()); }
  // The SISO series of one entry (output i, input j) over frequency.
  std::vector<std::complex<double>> entry(int i, int j) const {
    std::vector<std::complex<double>> v;
    v.reserve(h.size());
    for (const auto& m : h) v.push_back(m(i, j));
    return v;
  }
};

}  // namespace feedloop::model
