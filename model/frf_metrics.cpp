// mu_acc and error reduction, Eq. 70-72 (see frf_metrics.hpp).
#include "model/frf_metrics.hpp"

#include <cmath>    // std::abs, std::arg, std::remainder
#include <numbers>  // std::numbers::pi
#include <string>
#include <vector>

namespace feedloop::model {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

// Phase along frequency, made continuous (jumps of more than pi between neighbours removed).
std::vector<double> unwrapped_phase(std::span<const std::complex<double>> h) {
  std::vector<double> ph(h.size());
  double offset = 0.0;
  for (size_t k = 0; k < h.size(); ++k) {
    const double a = std::arg(h[k]);
    if (k > 0) {
      const double prev = ph[k - 1] - offset;  // previous wrapped value
      const double d = a - prev;
      if (d > std::numbers::pi) offset -= kTwoPi;
      if (d < -std::numbers::pi) offset += kTwoPi;
    }
    ph[k] = a + offset;
  }
  return ph;
}

Status check_sizes(size_t a, size_t b) {
  if (a == 0) return Error{"FRF metric needs at least one frequency point", {}};
  if (a != b)
    return Error{"FRF metric needs series of equal length (" + std::to_string(a) + " vs " +
                     std::to_string(b) + ")",
                 {}};
  return {};
}

Status check_sets(const FrfSet& a, const FrfSet& b) {
  if (Status st = check_sizes(a.h.size(), b.h.size()); !st) return st;
  for (size_t k = 0; k < a.freq_hz.size() && k < b.freq_hz.size(); ++k)
    if (std::abs(a.freq_hz[k] - b.freq_hz[k]) > 1e-9 * (1.0 + std::abs(a.freq_hz[k])))
      return Error{"FRF sets are on different frequency grids (point " + std::to_string(k) + ")", {}};
  return {};
}

}  // namespace

const char* to_string(FrfQuantity q) {
  switch (q) {
    case FrfQuantity::Magnitude: return "magnitude";
    case FrfQuantity::Phase: return "phase";
    case FrfQuantity::ComplexValue: return "complex";
  }
  return "?";
}

Result<double> mu_err(std::span<const std::complex<double>> measured,
                      std::span<const std::complex<double>> predicted, FrfQuantity q) {
  if (Status st = check_sizes(measured.size(), predicted.size()); !st) return st.error();
  std::vector<double> pm, pp;
  if (q == FrfQuantity::Phase) {
    pm = unwrapped_phase(measured);
    pp = unwrapped_phase(predicted);
  }
  double sum = 0.0;
  int n = 0;
  for (size_t k = 0; k < measured.size(); ++k) {
    double num = 0.0, den = 0.0;
    switch (q) {
      case FrfQuantity::Magnitude:
        num = std::abs(std::abs(measured[k]) - std::abs(predicted[k]));
        den = std::abs(measured[k]);
        break;
      case FrfQuantity::Phase:
        num = std::abs(std::remainder(pp[k] - pm[k], kTwoPi));
        den = std::abs(pm[k]);
        break;
      case FrfQuantity::ComplexValue:
        num = std::abs(measured[k] - predicted[k]);
        den = std::abs(measured[k]);
        break;
    }
    if (!std::isfinite(num) || !std::isfinite(den)) return Error{"FRF metric met a non-finite value", {}};
    if (den == 0.0) continue;
    sum += num / den;
    ++n;
  }
  if (n == 0) return Error{"FRF metric: every measured point is zero", {}};
  return sum / n * 100.0;  // Eq. 71
}

Result<double> mu_acc(std::span<const std::complex<double>> measured,
                      std::span<const std::complex<double>> predicted, FrfQuantity q) {
  auto e = mu_err(measured, predicted, q);
  if (!e) return e.error();
  return 100.0 - *e;  // Eq. 70
}

Result<double> error_reduction_pct(std::span<const std::complex<double>> measured,
                                   std::span<const std::complex<double>> predicted,
                                   std::span<const std::complex<double>> baseline, FrfQuantity q) {
  auto ep = mu_err(measured, predicted, q);
  if (!ep) return ep.error();
  auto eb = mu_err(measured, baseline, q);
  if (!eb) return eb.error();
  if (*eb == 0.0) return Error{"error reduction undefined: the baseline matches the measurement exactly", {}};
  return (*eb - *ep) / *eb * 100.0;  // Eq. 72
}

Result<Eigen::Matrix3d> mu_acc(const FrfSet& measured, const FrfSet& predicted, FrfQuantity q) {
  if (Status st = check_sets(measured, predicted); !st) return st.error();
  Eigen::Matrix3d out;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const auto m = measured.entry(i, j);
      const auto p = predicted.entry(i, j);
      auto v = mu_acc(m, p, q);
      if (!v) return v.error();
      out(i, j) = *v;
    }
  return out;
}

Result<Eigen::Matrix3d> error_reduction_pct(const FrfSet& measured, const FrfSet& predicted,
                                            const FrfSet& baseline, FrfQuantity q) {
  if (Status st = check_sets(measured, predicted); !st) return st.error();
  if (Status st = check_sets(measured, baseline); !st) return st.error();
  Eigen::Matrix3d out;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const auto m = measured.entry(i, j);
      const auto p = predicted.entry(i, j);
      const auto b = baseline.entry(i, j);
      auto v = error_reduction_pct(m, p, b, q);
      if (!v) return v.error();
      out(i, j) = *v;
    }
  return out;
}

}  // namespace feedloop::model
