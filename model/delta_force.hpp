// How the end-effector's inertial force reaches the carriages (delta-lpv-receptance-coupling.txt,
// Sect. III-B, Eq. 14-26 and 69), in two forms behind one switch.
//
// Paper (Eq. 19-25, 69; the default, Table I was fitted through it):
//   r_i = [D_e cos phi_i - delta_x, D_e sin phi_i - delta_y, -delta_z]              (Eq. 20)
//   L = [[I, I, I], [S(r_A), S(r_B), S(r_C)]] (6x9),  L f = [W X; 0]               (Eq. 21)
//   f = L^T (L L^T)^-1 u;  P_i = rows 3i..3i+2, columns 0..2 of L^+                (Eq. 22-23)
//   F_qi = Jbar_i^T P_i W(s) X,  Jbar_i = column i of Jbar                           (Eq. 25)
//   so F_q = T W(s) X with T = [Jbar_A^T P_A; Jbar_B^T P_B; Jbar_C^T P_C] = [alpha_ji] (Eq. 69).
// VirtualWork (DESIGN.md): the effector translates rigidly with X = Jbar q, so the generalised
// force on the carriages is F_q = Jbar^T W(s) X, i.e. T = Jbar^T. The mass offset delta does no
// work in pure translation and drops out.
// The paper's form splits the force twice (P_i, then Jbar_i^T): for a centred vertical effector
// each carriage carries m_e/9, against m_e/3 by virtual work.
#pragma once

#include <array>

#include <Eigen/Dense>

#include "model/delta_params.hpp"

namespace feedloop::model {

enum class ForceTransform { Paper, VirtualWork };

const char* to_string(ForceTransform f);

// Eq. 20, in mm.
std::array<Eigen::Vector3d, 3> moment_arms_mm(const DeltaParams& p);

// S(r) with S(r) v = r x v.
Eigen::Matrix3d skew(const Eigen::Vector3d& r);

// Eq. 21: L (6x9).
Eigen::Matrix<double, 6, 9> equilibrium_matrix(const DeltaParams& p);

// Eq. 22-23: P_A, P_B, P_C (dimensionless; independent of the length unit of r_i since the moment
// rows of u are zero).
std::array<Eigen::Matrix3d, 3> force_distribution(const DeltaParams& p);

// T with F_q = T W(s) X for the chosen form (rows = carriages, columns = task axes x, y, z).
Eigen::Matrix3d force_transform(const DeltaParams& p, const Eigen::Matrix3d& jbar, ForceTransform form);

}  // namespace feedloop::model
