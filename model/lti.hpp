// Linear time-invariant models shared by the gantry and delta models: continuous state space,
// transfer functions as polynomial ratios, frequency responses, static gains and polynomial roots.
// Units are whatever the model uses (SI inside model/); s is in rad/s.
#pragma once

#include <complex>
#include <vector>

#include <Eigen/Dense>

#include "core/result.hpp"
#include "model/frequency_grid.hpp"

namespace feedloop::model {

using Complex = std::complex<double>;

// dx/dt = A x + B u,  y = C x + D u.
struct StateSpace {
  Eigen::MatrixXd A, B, C, D;

  int states() const { return static_cast<int>(A.rows()); }
  int inputs() const { return static_cast<int>(B.cols()); }
  int outputs() const { return static_cast<int>(C.rows()); }
};

// Checks that A is n x n, B n x m, C p x n, D p x m and that every entry is finite.
Status check_dimensions(const StateSpace& sys);

// H(s) = C (sI - A)^-1 B + D, a p x m complex matrix.
Eigen::MatrixXcd frequency_response(const StateSpace& sys, Complex s);
// H(j 2 pi f) at every grid point.
std::vector<Eigen::MatrixXcd> frequency_response(const StateSpace& sys, const FrequencyGrid& grid);

// H(0) = D - C A^-1 B; an error if A is singular (a pole at s = 0).
Result<Eigen::MatrixXd> dc_gain(const StateSpace& sys);

// The single-input single-output subsystem from input `in` to output `out`.
StateSpace select(const StateSpace& sys, int out, int in);

// Eigenvalues of A.
Eigen::VectorXcd poles(const StateSpace& sys);

// Roots of a polynomial given in descending powers (c[0] s^n + ... + c[n]), by the eigenvalues
// of its companion matrix. Leading zeros are dropped; an all-zero or constant polynomial has no roots.
std::vector<Complex> polynomial_roots(const std::vector<double>& coeffs_desc);

// Product of two polynomials in descending powers.
std::vector<double> polynomial_multiply(const std::vector<double>& a, const std::vector<double>& b);

// Value of a polynomial (descending powers) at s, by Horner's rule.
Complex polynomial_value(const std::vector<double>& coeffs_desc, Complex s);

// num(s) / den(s), coefficients in descending powers of s.
struct TransferFunction {
  std::vector<double> num;
  std::vector<double> den;

  Complex evaluate(Complex s) const { return polynomial_value(num, s) / polynomial_value(den, s); }
  Complex at_hz(double f_hz) const;
  // num(0)/den(0); infinite when den(0) = 0.
  double dc_gain() const;
  std::vector<Complex> zeros() const { return polynomial_roots(num); }
  std::vector<Complex> poles() const { return polynomial_roots(den); }
};

// det(zI - M) as a polynomial in descending powers (from the eigenvalues of M).
std::vector<double> characteristic_polynomial(const Eigen::MatrixXd& m);

// The transfer function of a single-input single-output realisation (A, B, C, D), in s for a
// continuous system or in z for a discrete one (same algebra):
//   num = D det(zI - A) + det(zI - A + B C) - det(zI - A),  den = det(zI - A).
// Its zeros are the transmission zeros (e.g. for ZPETC). Error unless B is n x 1 and C is 1 x n.
Result<TransferFunction> siso_transfer_function(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B,
                                                const Eigen::MatrixXd& C, const Eigen::MatrixXd& D);

}  // namespace feedloop::model
