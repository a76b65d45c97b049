// Sanathanan-Koerner rational fit and the Levenberg-Marquardt wrapper (rational_fit.hpp).
#include "ident/delta/rational_fit.hpp"

#include <cmath>
#include <numbers>
#include <string>

#include <unsupported/Eigen/NonLinearOptimization>
#include <unsupported/Eigen/NumericalDiff>

namespace feedloop::ident::delta {

Result<model::TransferFunction> fit_rational(std::span<const double> freq_hz,
                                             std::span<const std::complex<double>> h,
                                             const RationalFitSpec& spec) {
  const int nb = spec.num_order, na = spec.den_order;
  const int n_unknown = nb + 1 + na;
  const auto n_pts = static_cast<int>(freq_hz.size());
  if (nb < 0 || na < 1 || nb > na + 1) return Error{"rational fit: need 0 <= num_order <= den_order + 1, den_order >= 1", {}};
  if (freq_hz.size() != h.size()) return Error{"rational fit: frequency and FRF lengths differ", {}};
  if (2 * n_pts < n_unknown + 1) return Error{"rational fit: too few frequency points", {}};
  double f_max = 0.0;
  for (double f : freq_hz) f_max = std::max(f_max, f);
  if (!(f_max > 0.0)) return Error{"rational fit: frequencies must be > 0", {}};
  const double w0 = 2.0 * std::numbers::pi * f_max;

  // Unknowns: b_0..b_nb (numerator, ascending powers of s~ = s / w0), a_0..a_{na-1} (denominator,
  // s~^na monic). Row k: sum b_i s~^i - H sum a_i s~^i = H s~^na, weighted.
  std::vector<std::complex<double>> sn(static_cast<size_t>(n_pts));
  for (int k = 0; k < n_pts; ++k) sn[static_cast<size_t>(k)] = {0.0, 2.0 * std::numbers::pi * freq_hz[static_cast<size_t>(k)] / w0};
  std::vector<double> weight(static_cast<size_t>(n_pts), 1.0);
  Eigen::VectorXd theta = Eigen::VectorXd::Zero(n_unknown);
  for (int it = 0; it < std::max(1, spec.iterations); ++it) {
    Eigen::MatrixXd a(2 * n_pts, n_unknown);
    Eigen::VectorXd rhs(2 * n_pts);
    for (int k = 0; k < n_pts; ++k) {
      const auto ku = static_cast<size_t>(k);
      const std::complex<double> s = sn[ku], hk = h[ku];
      double w = weight[ku];
      if (spec.relative) w /= std::max(std::abs(hk), 1e-300);
      std::complex<double> p = 1.0;
      for (int i = 0; i <= nb; ++i, p *= s) {
        a(2 * k, i) = w * p.real();
        a(2 * k + 1, i) = w * p.imag();
      }
      p = 1.0;
      for (int i = 0; i < na; ++i, p *= s) {
        const std::complex<double> v = -hk * p;
        a(2 * k, nb + 1 + i) = w * v.real();
        a(2 * k + 1, nb + 1 + i) = w * v.imag();
      }
      const std::complex<double> r = hk * p;  // p = s^na here
      rhs[2 * k] = w * r.real();
      rhs[2 * k + 1] = w * r.imag();
    }
    // Column scaling keeps the normal problem well conditioned.
    Eigen::VectorXd col = a.colwise().norm().transpose();
    for (int j = 0; j < n_unknown; ++j)
      if (!(col[j] > 0.0)) return Error{"rational fit: degenerate regressor (all-zero column)", {}};
    const Eigen::MatrixXd as = a * col.cwiseInverse().asDiagonal();
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(as);
    if (qr.rank() < n_unknown) return Error{"rational fit: rank-deficient least-squares problem", {}};
    theta = qr.solve(rhs).cwiseQuotient(col);
    if (!theta.allFinite()) return Error{"rational fit: non-finite coefficients", {}};
    // Sanathanan-Koerner reweighting by the current denominator.
    for (int k = 0; k < n_pts; ++k) {
      const std::complex<double> s = sn[static_cast<size_t>(k)];
      std::complex<double> d = 0.0, p = 1.0;
      for (int i = 0; i < na; ++i, p *= s) d += theta[nb + 1 + i] * p;
      d += p;
      weight[static_cast<size_t>(k)] = 1.0 / std::max(std::abs(d), 1e-300);
    }
  }
  // Back to s in rad/s, monic: multiply N and D by w0^na.
  model::TransferFunction tf;
  tf.num.assign(static_cast<size_t>(nb + 1), 0.0);
  tf.den.assign(static_cast<size_t>(na + 1), 0.0);
  for (int i = 0; i <= nb; ++i) tf.num[static_cast<size_t>(nb - i)] = theta[i] * std::pow(w0, na - i);
  for (int i = 0; i < na; ++i) tf.den[static_cast<size_t>(na - i)] = theta[nb + 1 + i] * std::pow(w0, na - i);
  tf.den[0] = 1.0;
  return tf;
}

namespace {

struct Functor {
  using Scalar = double;
  using InputType = Eigen::VectorXd;
  using ValueType = Eigen::VectorXd;
  using JacobianType = Eigen::MatrixXd;
  enum { InputsAtCompileTime = Eigen::Dynamic, ValuesAtCompileTime = Eigen::Dynamic };

  const ResidualFn* f = nullptr;
  int n_in = 0, n_out = 0;
  mutable int evaluations = 0;

  int inputs() const { return n_in; }
  int values() const { return n_out; }
  int operator()(const Eigen::VectorXd& x, Eigen::VectorXd& r) const {
    ++evaluations;
    r.resize(n_out);
    (*f)(x, r);
    // A non-finite residual (a parameter wandered out of the physical range) is made large
    // rather than NaN so that the step is rejected.
    for (int i = 0; i < n_out; ++i)
      if (!std::isfinite(r[i])) r[i] = 1e10;
    return 0;
  }
};

}  // namespace

Result<LsqSolution> levenberg_marquardt(const ResidualFn& f, int n_residuals, const Eigen::VectorXd& x0,
                                        int max_evaluations) {
  const auto n = static_cast<int>(x0.size());
  if (n < 1 || n_residuals < n) return Error{"least squares: need at least as many residuals as unknowns", {}};
  Eigen::VectorXd r0(n_residuals);
  f(x0, r0);
  if (!r0.allFinite()) return Error{"least squares: residual not finite at the initial guess", {}};
  Functor fun;
  fun.f = &f;
  fun.n_in = n;
  fun.n_out = n_residuals;
  Eigen::NumericalDiff<Functor, Eigen::Central> diff(fun, 1e-7);
  Eigen::LevenbergMarquardt<Eigen::NumericalDiff<Functor, Eigen::Central>> lm(diff);
  lm.parameters.maxfev = max_evaluations;
  lm.parameters.xtol = 1e-12;
  lm.parameters.ftol = 1e-14;
  LsqSolution sol;
  sol.x = x0;
  lm.minimize(sol.x);
  Eigen::VectorXd r(n_residuals);
  f(sol.x, r);
  if (!r.allFinite()) return Error{"least squares: residual not finite at the solution", {}};
  sol.rms = std::sqrt(r.squaredNorm() / n_residuals);
  sol.evaluations = diff.evaluations + 2;
  return sol;
}

}  // namespace feedloop::ident::delta
