// Small-signal models of the simulator's own plants: a finite-difference linearisation
// dx/dt = A x + B u, y = C x around an operating point, and its frequency response
// C (j w I - A)^-1 B. Used by the tests to check the plants against the papers' transfer
// functions (thesis Eq. 16-18, delta paper Eq. 29) and by anyone who wants a plant's FRF.
#pragma once

#include <complex>
#include <functional>

#include <Eigen/Dense>

namespace feedloop::sim {

struct LinearModel {
  Eigen::MatrixXd a;  // n x n
  Eigen::MatrixXd b;  // n x m
  Eigen::MatrixXd c;  // p x n
};

using Dynamics = std::function<Eigen::VectorXd(const Eigen::VectorXd& x, const Eigen::VectorXd& u)>;

// Central differences of f around (x0, u0); perturbation dx[i] for state i and du for every input.
// The output map C is given (the plants' outputs are states).
LinearModel linearize_dynamics(const Dynamics& f, const Eigen::VectorXd& x0, const Eigen::VectorXd& u0,
                               const Eigen::VectorXd& dx, double du, const Eigen::MatrixXd& c);

// p x m frequency response matrix at freq_hz.
Eigen::MatrixXcd frequency_response(const LinearModel& m, double freq_hz);

}  // namespace feedloop::sim
