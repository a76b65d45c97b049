// Continuous LTI helpers (see lti.hpp).
#include "model/lti.hpp"

#include <algorithm>  // std::max
#include <cmath>     // std::isfinite, std::abs
#include <numbers>   // std::numbers::pi
#include <string>

namespace feedloop::model {

Status check_dimensions(const StateSpace& sys) {
  const auto n = sys.A.rows();
  const auto m = sys.B.cols();
  const auto p = sys.C.rows();
  if (sys.A.cols() != n || sys.B.rows() != n || sys.C.cols() != n || sys.D.rows() != p ||
      sys.D.cols() != m) {
    return Error{"state space dimensions do not match: A " + std::to_string(sys.A.rows()) + "x" +
                     std::to_string(sys.A.cols()) + ", B " + std::to_string(sys.B.rows()) + "x" +
                     std::to_string(sys.B.cols()) + ", C " + std::to_string(sys.C.rows()) + "x" +
                     std::to_string(sys.C.cols()) + ", D " + std::to_string(sys.D.rows()) + "x" +
                     std::to_string(sys.D.cols()),
                 {}};
  }
  if (!sys.A.allFinite() || !sys.B.allFinite() || !sys.C.allFinite() || !sys.D.allFinite())
    return Error{"state space has a non-finite entry", {}};
  return {};
}

Eigen::MatrixXcd frequency_response(const StateSpace& sys, Complex s) {
  Eigen::MatrixXcd sIA = -sys.A.cast<Complex>();
  sIA.diagonal().array() += s;
  Eigen::MatrixXcd x = sIA.partialPivLu().solve(sys.B.cast<Complex>());
  return sys.C.cast<Complex>() * x + sys.D.cast<Complex>();
}

std::vector<Eigen::MatrixXcd> frequency_response(const StateSpace& sys, const FrequencyGrid& grid) {
  std::vector<Eigen::MatrixXcd> out;
  out.reserve(static_cast<size_t>(grid.size()));
  for (int k = 0; k < grid.size(); ++k)
    out.push_back(frequency_response(sys, Complex(0.0, 2.0 * std::numbers::pi * grid.at_hz(k))));
  return out;
}

Result<Eigen::MatrixXd> dc_gain(const StateSpace& sys) {
  Eigen::FullPivLU<Eigen::MatrixXd> lu(sys.A);
  if (!lu.isInvertible()) return Error{"A is singular (pole at s = 0): no finite static gain", {}};
  return Eigen::MatrixXd(sys.D - sys.C * lu.solve(sys.B));
}

StateSpace select(const StateSpace& sys, int out, int in) {
  return StateSpace{sys.A, sys.B.col(in), sys.C.row(out), sys.D.block(out, in, 1, 1)};
}

Eigen::VectorXcd poles(const StateSpace& sys) {
  if (sys.states() == 0) return {};
  return Eigen::EigenSolver<Eigen::MatrixXd>(sys.A, false).eigenvalues();
}

std::vector<Complex> polynomial_roots(const std::vector<double>& coeffs_desc) {
  size_t first = 0;
  while (first < coeffs_desc.size() && coeffs_desc[first] == 0.0) ++first;
  if (coeffs_desc.size() - first < 2) return {};
  const int n = static_cast<int>(coeffs_desc.size() - first) - 1;
  const double lead = coeffs_desc[first];
  // Companion matrix: first row -c[k]/c[0], ones on the subdiagonal.
  Eigen::MatrixXd comp = Eigen::MatrixXd::Zero(n, n);
  for (int k = 0; k < n; ++k) comp(0, k) = -coeffs_desc[first + 1 + static_cast<size_t>(k)] / lead;
  for (int k = 1; k < n; ++k) comp(k, k - 1) = 1.0;
  const Eigen::VectorXcd ev = Eigen::EigenSolver<Eigen::MatrixXd>(comp, false).eigenvalues();
  return std::vector<Complex>(ev.data(), ev.data() + ev.size());
}

std::vector<double> polynomial_multiply(const std::vector<double>& a, const std::vector<double>& b) {
  if (a.empty() || b.empty()) return {};
  std::vector<double> r(a.size() + b.size() - 1, 0.0);
  for (size_t i = 0; i < a.size(); ++i)
    for (size_t j = 0; j < b.size(); ++j) r[i + j] += a[i] * b[j];
  return r;
}

Complex polynomial_value(const std::vector<double>& coeffs_desc, Complex s) {
  Complex v = 0.0;
  for (double c : coeffs_desc) v = v * s + c;
  return v;
}

std::vector<double> characteristic_polynomial(const Eigen::MatrixXd& m) {
  std::vector<Complex> c{1.0};
  if (m.rows() > 0) {
    const Eigen::VectorXcd ev = Eigen::EigenSolver<Eigen::MatrixXd>(m, false).eigenvalues();
    for (int k = 0; k < ev.size(); ++k) {
      std::vector<Complex> next(c.size() + 1, 0.0);
      for (size_t i = 0; i < c.size(); ++i) {
        next[i] += c[i];
        next[i + 1] -= c[i] * ev(k);
      }
      c.swap(next);
    }
  }
  std::vector<double> r(c.size());
  for (size_t i = 0; i < c.size(); ++i) r[i] = c[i].real();  // complex pairs: imaginary parts cancel
  return r;
}

Result<TransferFunction> siso_transfer_function(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B,
                                                const Eigen::MatrixXd& C, const Eigen::MatrixXd& D) {
  if (Status st = check_dimensions(StateSpace{A, B, C, D}); !st) return st.error();
  if (B.cols() != 1 || C.rows() != 1) return Error{"siso_transfer_function needs one input and one output", {}};
  const std::vector<double> den = characteristic_polynomial(A);
  const std::vector<double> closed = characteristic_polynomial(A - B * C);
  std::vector<double> num(den.size());
  for (size_t i = 0; i < den.size(); ++i) num[i] = D(0, 0) * den[i] + closed[i] - den[i];
  // Drop leading coefficients that are rounding noise (relative to the largest one).
  double scale = 0.0;
  for (double v : num) scale = std::max(scale, std::abs(v));
  size_t first = 0;
  while (first + 1 < num.size() && std::abs(num[first]) <= 1e-12 * scale) ++first;
  num.erase(num.begin(), num.begin() + static_cast<std::ptrdiff_t>(first));
  return TransferFunction{num, den};
}

Complex TransferFunction::at_hz(double f_hz) const {
  return evaluate(Complex(0.0, 2.0 * std::numbers::pi * f_hz));
}

double TransferFunction::dc_gain() const {
  const double d = den.empty() ? 0.0 : den.back();
  const double n = num.empty() ? 0.0 : num.back();
  return n / d;
}

}  // namespace feedloop::model
