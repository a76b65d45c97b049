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

// The plants' fixed RK4 step from their fastest mode: h * omega_max <= kRk4HOmegaMax, omega_max the
// largest |eigenvalue| of the linearised plant (rad/s). RK4 is stable to |h lambda| = 2.79 on the
// real axis and 2.83 on the imaginary axis; at h omega = 1 it damps an undamped mode by 0.6 % per
// step and gets a real mode's decay per step right within 2 % (exp(-1) = 0.368 against 0.375), and
// every slower mode (the ones the encoder sees, < 1 kHz) far better (the error falls as (h
// omega)^5). docs/simulator.md, "Integration".
inline constexpr double kRk4HOmegaMax = 1.0;

// Largest |eigenvalue| of a (rad/s).
double fastest_mode_rad_s(const Eigen::MatrixXd& a);
// The substep rate for a fastest mode omega_max: omega_max / kRk4HOmegaMax rounded up to a whole
// kHz (so that drives updated at a round rate can land on substeps), at least 1 kHz.
double substep_hz_for(double omega_max_rad_s);

}  // namespace feedloop::sim
