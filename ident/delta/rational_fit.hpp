// Frequency-domain fitting tools for the delta identification (docs/ident_delta.md):
//   - a rational transfer function fitted to a measured FRF by Sanathanan-Koerner iterations
//     (linear least squares on N(s) - H D(s), reweighted by the previous denominator), the
//     "fit a 4th-order FRF" step of Eq. 42 and the second-order fit of Eq. 46;
//   - a Levenberg-Marquardt wrapper (Eigen's unsupported MINPACK port, numerical Jacobian) for the
//     structured fits that follow (carriage parameters, b_j and k_j of Eq. 66-69).
#pragma once

#include <complex>
#include <functional>
#include <span>

#include <Eigen/Dense>

#include "core/result.hpp"
#include "model/lti.hpp"

namespace feedloop::ident::delta {

struct RationalFitSpec {
  int num_order = 2;  // degree of N(s)
  int den_order = 4;  // degree of D(s), monic
  int iterations = 20;
  // true: each point weighted by 1/|H| (relative error, spreads the fit over a wide magnitude
  // range); false: absolute error.
  bool relative = true;
};

// Fits H(j 2 pi f) ~ N(s)/D(s). Frequencies are scaled internally (s / (2 pi f_max)) for
// conditioning; the result is in rad/s with a monic denominator. Error for too few points or a
// rank-deficient problem.
Result<model::TransferFunction> fit_rational(std::span<const double> freq_hz,
                                             std::span<const std::complex<double>> h,
                                             const RationalFitSpec& spec);

// Residual function r(x) (size n_residuals) of a nonlinear least-squares problem.
using ResidualFn = std::function<void(const Eigen::VectorXd& x, Eigen::VectorXd& r)>;

struct LsqSolution {
  Eigen::VectorXd x;
  double rms = 0.0;        // sqrt(mean r^2) at x
  int evaluations = 0;     // residual evaluations
};

// Minimises |r(x)|^2 from x0. Error when the residual is not finite at x0.
Result<LsqSolution> levenberg_marquardt(const ResidualFn& f, int n_residuals, const Eigen::VectorXd& x0,
                                        int max_evaluations = 4000);

}  // namespace feedloop::ident::delta
