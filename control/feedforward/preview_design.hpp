// Offline design (configure time, allocates) of the finite-preview least-squares inverse that
// every model-based feedforward of control/feedforward/ runs: given a discrete model of the plant
// (motor command -> carriage position) it finds the command sequence that minimises
//
//   J = sum_k |y_k - r_k|^2 + rho |v_k - r_{k+d}|^2                                    (1)
//
// over an infinite horizon, knowing the reference P samples ahead and assuming it holds still
// after that. The answer is a preview law (Tomizuka's preview control; Katayama et al. 1985):
//
//   v_k = -K x_k + sum_{i=0..P} F_i r_{k+i}                                              (2)
//
// with x_k the state of the feedforward's own copy of the model driven by v. Unlike plain model
// inversion it never cancels a zero: a non-minimum-phase zero (the delta carriage's electrical zero
// at +674 rad/s, Eq. 34 of the delta paper with d1 < 0; the ZOH/FOH sampling zeros outside the
// unit circle of the relative-degree-4 gantry model, thesis Eq. 16) is handled by using the
// preview, and the closed loop A - B K of the internal model is stable by construction (LQ).
// It is MIMO as is: the delta's coupled 3x3 G(s) of Eq. 29 needs no term-by-term inversion.
// docs/feedforward.md derives (2) and the choice of rho; docs/decisions.md has the measurements.
//
// Discretisation follows how the command reaches the motor: `zero_order` holds u_k over the
// period; `linear` (default) moves the motor linearly from u_k at t_k to u_{k+1} at t_{k+1}
// (what a step generator fed one target per period does). The linear hold is realised with the
// next command as input (v_k = u_{k+1}) and the current one as a state, so (2) stays causal.
#pragma once

#include <vector>

#include <Eigen/Dense>

#include "core/result.hpp"
#include "model/discrete.hpp"
#include "model/lti.hpp"

namespace feedloop::control {

enum class CommandHold { zero_order, linear };

const char* to_string(CommandHold h);

// The model the inverse acts on, at the servo period. Input of the result: zero_order: u_k;
// linear: v_k = u_{k+1}, with u_k the last `inputs` states. Output: y_k (strictly proper).
// Errors: bad dimensions, D != 0, period <= 0, exponential overflow.
Result<model::DiscreteStateSpace> discretize_for_hold(const model::StateSpace& sys, double period_s,
                                                      CommandHold hold);

struct PreviewWeights {
  double rho = 1e-4;  // weight of the command's deviation from the reference in (1), per mm^2
};

// A designed law (2) at one operating point, with the model it runs on.
struct PreviewInverse {
  Eigen::MatrixXd A, B;            // internal model x_{k+1} = A x_k + B v_k (n x n, n x m)
  Eigen::MatrixXd K;               // m x n
  std::vector<Eigen::MatrixXd> F;  // F_0 .. F_P, each m x m
  Eigen::MatrixXd rest_state;      // n x m: x at rest under a constant reference r (x = rest_state r)
  double closed_loop_radius = 0;   // spectral radius of A - B K (< 1)
};

// Designs (2) for the model `d` (from discretize_for_hold) with P = preview_samples.
// ref_offset d of (1): 0 for zero_order, 1 for linear (v_k is the command at t_{k+1}).
// Errors: P < 1 + d, rho <= 0, a model without a finite static gain, Riccati not converging.
Result<PreviewInverse> design_preview_inverse(const model::DiscreteStateSpace& d, int preview_samples,
                                              int ref_offset, const PreviewWeights& w);

// The stabilising solution X of the discrete algebraic Riccati equation
//   X = A' X A - A' X B (R + B' X B)^-1 B' X A + Q
// by the structure-preserving doubling algorithm (quadratic convergence). R must be invertible.
Result<Eigen::MatrixXd> solve_dare(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& Q,
                                   const Eigen::MatrixXd& R);

}  // namespace feedloop::control
