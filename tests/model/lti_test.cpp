// LTI helpers: polynomial roots, frequency response and static gain of a known system.
#include <gtest/gtest.h>

#include <algorithm>

#include "model/lti.hpp"

namespace fm = feedloop::model;

TEST(Lti, PolynomialRoots) {
  // (s - 2)(s + 3)(s^2 + 2s + 5) = s^4 + 3 s^3 + 1 s^2 - 1 s - 30... computed by multiply.
  const auto p = fm::polynomial_multiply(fm::polynomial_multiply({1, -2}, {1, 3}), {1, 2, 5});
  auto r = fm::polynomial_roots(p);
  ASSERT_EQ(r.size(), 4u);
  std::sort(r.begin(), r.end(), [](auto a, auto b) { return a.real() == b.real() ? a.imag() < b.imag() : a.real() < b.real(); });
  EXPECT_NEAR(r[0].real(), -3.0, 1e-9);
  EXPECT_NEAR(r[1].real(), -1.0, 1e-9);
  EXPECT_NEAR(r[1].imag(), -2.0, 1e-9);
  EXPECT_NEAR(r[3].real(), 2.0, 1e-9);
  EXPECT_TRUE(fm::polynomial_roots({0.0, 0.0, 4.0}).empty());
  EXPECT_EQ(fm::polynomial_roots({0.0, 2.0, 4.0}).size(), 1u);
}

TEST(Lti, FirstOrderFrequencyResponseAndGain) {
  // dx = -a x + a u: low pass with gain 1 and corner a rad/s.
  const double a = 10.0;
  fm::StateSpace s{Eigen::MatrixXd::Constant(1, 1, -a), Eigen::MatrixXd::Constant(1, 1, a),
                   Eigen::MatrixXd::Ones(1, 1), Eigen::MatrixXd::Zero(1, 1)};
  ASSERT_TRUE(fm::check_dimensions(s).ok());
  EXPECT_NEAR(std::abs(fm::frequency_response(s, fm::Complex(0, a))(0, 0)), 1 / std::sqrt(2.0), 1e-12);
  EXPECT_NEAR((*fm::dc_gain(s))(0, 0), 1.0, 1e-12);
  s.A(0, 0) = 0.0;
  EXPECT_FALSE(fm::dc_gain(s).ok());
  s.B = Eigen::MatrixXd::Ones(2, 1);
  EXPECT_FALSE(fm::check_dimensions(s).ok());
}
