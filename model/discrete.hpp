// Discrete-time realisations for the servo thread (feedforward, observers): zero-order-hold
// discretisation of a continuous StateSpace, and a filter object that steps it without allocating.
//
// ZOH (exact for piecewise-constant inputs): with the augmented matrix
//   M = [[A, B], [0, 0]] * T,   exp(M) = [[Ad, Bd], [0, I]],
// x[k+1] = Ad x[k] + Bd u[k],  y[k] = C x[k] + D u[k]. Ad and Bd come from Eigen's matrix exponential.
// Note: ZOH maps a right-half-plane zero (the delta carriage's electrical zero at +674 rad/s) to a
// zero outside the unit circle; the discrete model stays non-minimum-phase (DESIGN.md).
#pragma once

#include <complex>

#include <Eigen/Dense>

#include "core/result.hpp"
#include "model/lti.hpp"

namespace feedloop::model {

struct DiscreteStateSpace {
  Eigen::MatrixXd Ad, Bd, C, D;
  double period_s = 0.0;

  int states() const { return static_cast<int>(Ad.rows()); }
  int inputs() const { return static_cast<int>(Bd.cols()); }
  int outputs() const { return static_cast<int>(C.rows()); }
};

// ZOH discretisation at period_s (> 0). Errors: bad dimensions, non-finite entries, period <= 0.
Result<DiscreteStateSpace> discretize_zoh(const StateSpace& sys, double period_s);

// H(z) = C (zI - Ad)^-1 Bd + D at z = exp(j 2 pi f T).
Eigen::MatrixXcd frequency_response(const DiscreteStateSpace& sys, double freq_hz);

// H(1) = D + C (I - Ad)^-1 Bd; an error if Ad has an eigenvalue at 1.
Result<Eigen::MatrixXd> dc_gain(const DiscreteStateSpace& sys);

// Steps a DiscreteStateSpace one sample at a time.
// Owner: one thread (the servo thread in the daemon). configure() allocates; reset() and step()
// do not allocate, lock or throw (RT-safe).
class DiscreteLtiFilter {
 public:
  Status configure(const DiscreteStateSpace& sys);
  // RT-safe. Zero state.
  void reset();
  // RT-safe. Sets the state to the equilibrium for a constant input u (length inputs()):
  // x = (I - Ad)^-1 Bd u, precomputed at configure time (zero if Ad has an eigenvalue at 1).
  void reset_to_steady_state(const double* u);
  // RT-safe. y[k] = C x[k] + D u[k], then x[k+1] = Ad x[k] + Bd u[k].
  // u has inputs() entries, y has outputs() entries.
  void step(const double* u, double* y);

  const Eigen::VectorXd& state() const { return x_; }
  const DiscreteStateSpace& system() const { return sys_; }

 private:
  DiscreteStateSpace sys_;
  Eigen::MatrixXd steady_state_map_;  // (I - Ad)^-1 Bd
  Eigen::VectorXd x_;
  Eigen::VectorXd x_next_;
};

}  // namespace feedloop::model
