// The frequency-domain building blocks of the delta LPV model (delta-lpv-receptance-coupling.txt):
// sub-model 1, the decoupled carriage (Sect. IV-A, Eq. 30-44), and the end-effector's inertial
// dynamics W(s) (Sect. IV-B, Eq. 45-67). All in SI, s in rad/s.
#pragma once

#include <Eigen/Dense>

#include "model/delta_params.hpp"
#include "model/lti.hpp"

namespace feedloop::model {

// Eq. 32: G_qd,m(s) = (c s + k) / (m s^2 + (c + b) s + k), m = m_c + m_f/2 (Eq. 30).
Complex carriage_mechanical(const DeltaParams& p, Complex s);
// Eq. 34: G_qd,e(s) = (d1 s + d0) / (s^2 + d2 s + d0); static gain 1, RHP zero at -d0/d1 when d1 < 0.
Complex carriage_electrical(const DeltaParams& p, Complex s);
// Eq. 31: G_qd(s) = G_qd,m(s) G_qd,e(s), commanded to actual carriage position.
Complex carriage_position(const DeltaParams& p, Complex s);
// Eq. 44: G_Fq(s) = -1 / (m s^2 + (c + b) s + k), disturbance force (N) to carriage position (m).
Complex carriage_force(const DeltaParams& p, Complex s);

// Eq. 31/42 as one 4th-order polynomial ratio (g2 s^2 + g1 s + g0)/(s^4 + h3 s^3 + ... + h0),
// coefficients as in Eq. 43.
TransferFunction carriage_position_tf(const DeltaParams& p);
// Eq. 34 alone.
TransferFunction carriage_electrical_tf(const DeltaParams& p);

// Sub-model 1 (Eq. 1) as state space for one carriage: inputs [q_d, F_q] (commanded position,
// external force in N), output q; states [z1, z2, q, q'] with the electrical filter in position
// units (z1 = d0 xi, z2 = sqrt(d0) xi', u = d0 xi + d1 xi'). SI (m, N).
//   q = G_qd(s) q_d + G_Fq(s) F_q                                                      (Eq. 1)
StateSpace carriage_state_space(const DeltaParams& p);

// Eq. 68: characteristic polynomial D_ji(s) (descending powers, s^4..s^0) of carriage i's
// mechanical FRF when the effector moves along task axis j alone, alpha = alpha_ji of Eq. 69.
// AsPrinted reproduces the paper's s^2 term alpha (c+b) b_j; Expanded is the actual expansion of
//   (m s^2 + (c+b) s + k)(m2 s^2 + b_j s + k_j) + alpha s^2 (m1 m2 s^2 + (m1+m2)(b_j s + k_j)),
// whose s^2 term has (c+b) b_j without alpha (DESIGN.md). They agree only when alpha = 1.
enum class Eq68Form { AsPrinted, Expanded };
std::vector<double> eq68_characteristic_polynomial(const DeltaParams& p, double alpha, int axis_j,
                                                   Eq68Form form);

// Eq. 61/67: diagonal of W(s), the end-effector's force (N) per displacement (m) per task axis:
//   w_j(s) = s^2 (m1 m2 s^2 + (m1 + m2)(b_j s + k_j)) / (m2 s^2 + b_j s + k_j),   j in {x, y, z};
// with m2 = 0: w_j(s) = m1 s^2 (rigid effector).
Eigen::Vector3cd effector_dynamic_stiffness(const DeltaParams& p, Complex s);

}  // namespace feedloop::model
