// Offline design of the finite-preview least-squares inverse (see preview_design.hpp).
#include "control/feedforward/preview_design.hpp"

#include <cmath>  // std::isfinite, std::abs

#include <unsupported/Eigen/MatrixFunctions>  // MatrixBase::exp

namespace feedloop::control {

const char* to_string(CommandHold h) { return h == CommandHold::linear ? "linear" : "zero_order"; }

Result<model::DiscreteStateSpace> discretize_for_hold(const model::StateSpace& sys, double period_s,
                                                      CommandHold hold) {
  if (Status st = model::check_dimensions(sys); !st) return st.error();
  if (sys.D.size() > 0 && sys.D.cwiseAbs().maxCoeff() != 0.0)
    return Error{"feedforward model must be strictly proper (D = 0)", {}};
  if (hold == CommandHold::zero_order) return model::discretize_zoh(sys, period_s);
  if (!(period_s > 0.0) || !std::isfinite(period_s)) return Error{"period must be positive and finite", {}};
  const int n = sys.states(), m = sys.inputs(), p = sys.outputs();
  // u(t) = u_k + (t - t_k)/T (u_{k+1} - u_k): exp([[A T, B T, 0], [0, 0, I], [0, 0, 0]]) =
  // [[Phi, Ga, Gb], ...] with Ga = int_0^T e^{A(T-s)} B ds, Gb = int_0^T e^{A(T-s)} B s/T ds, so
  // x_{k+1} = Phi x_k + (Ga - Gb) u_k + Gb u_{k+1}.
  Eigen::MatrixXd big = Eigen::MatrixXd::Zero(n + 2 * m, n + 2 * m);
  big.topLeftCorner(n, n) = sys.A * period_s;
  big.block(0, n, n, m) = sys.B * period_s;
  big.block(n, n + m, m, m).setIdentity();
  const Eigen::MatrixXd e = big.exp();
  const Eigen::MatrixXd phi = e.topLeftCorner(n, n);
  const Eigen::MatrixXd ga = e.block(0, n, n, m);
  const Eigen::MatrixXd gb = e.block(0, n + m, n, m);
  if (!phi.allFinite() || !ga.allFinite() || !gb.allFinite())
    return Error{"matrix exponential overflowed: the model is too fast or unstable for this period", {}};
  model::DiscreteStateSpace d;
  d.period_s = period_s;
  d.Ad = Eigen::MatrixXd::Zero(n + m, n + m);
  d.Ad.topLeftCorner(n, n) = phi;
  d.Ad.topRightCorner(n, m) = ga - gb;
  d.Bd = Eigen::MatrixXd::Zero(n + m, m);
  d.Bd.topRows(n) = gb;
  d.Bd.bottomRows(m).setIdentity();
  d.C = Eigen::MatrixXd::Zero(p, n + m);
  d.C.leftCols(n) = sys.C;
  d.D = Eigen::MatrixXd::Zero(p, m);
  return d;
}

Result<Eigen::MatrixXd> solve_dare(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& Q,
                                   const Eigen::MatrixXd& R) {
  const int n = static_cast<int>(A.rows());
  // SDA (Chu, Fan, Lin 2005): A_0 = A, G_0 = B R^-1 B', H_0 = Q;
  //   W = I + G H, A' = A W^-1 A, G' = G + A W^-1 G A^T, H' = H + A^T H W^-1 A; H -> X.
  Eigen::MatrixXd a = A;
  Eigen::MatrixXd g = B * R.ldlt().solve(B.transpose());
  Eigen::MatrixXd h = Q;
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(n, n);
  for (int it = 0; it < 60; ++it) {
    Eigen::PartialPivLU<Eigen::MatrixXd> w(I + g * h);
    const Eigen::MatrixXd wa = w.solve(a);   // W^-1 A
    const Eigen::MatrixXd wg = w.solve(g);   // W^-1 G
    const Eigen::MatrixXd h_next = h + a.transpose() * h * wa;
    g = g + a * wg * a.transpose();
    a = a * wa;
    g = 0.5 * (g + g.transpose());
    const double change = (h_next - h).norm();
    h = 0.5 * (h_next + h_next.transpose());
    if (!h.allFinite()) break;
    if (change <= 1e-13 * (1.0 + h.norm())) return h;
  }
  return Error{"Riccati equation did not converge (is the model stable?)", {}};
}

Result<PreviewInverse> design_preview_inverse(const model::DiscreteStateSpace& d, int preview_samples,
                                              int ref_offset, const PreviewWeights& w) {
  const int P = preview_samples;
  if (ref_offset < 0 || P < 1 + ref_offset)
    return Error{"preview of " + std::to_string(P) + " samples is too short (needs at least " +
                     std::to_string(1 + ref_offset) + ")",
                 {}};
  if (!(w.rho > 0.0) || !std::isfinite(w.rho)) return Error{"feedforward weight rho must be > 0", {}};
  const int n = d.states(), m = d.inputs();
  if (d.outputs() != m) return Error{"feedforward model must be square (as many outputs as inputs)", {}};
  const Eigen::MatrixXd& A = d.Ad;
  const Eigen::MatrixXd& B = d.Bd;
  const Eigen::MatrixXd& C = d.C;
  const Eigen::MatrixXd R = w.rho * Eigen::MatrixXd::Identity(m, m);
  auto X = solve_dare(A, B, C.transpose() * C, R);  // (1) with Q = I on the output error
  if (!X) return X.error();
  const Eigen::MatrixXd& Xs = X.value();

  PreviewInverse out;
  out.A = A;
  out.B = B;
  const Eigen::MatrixXd M = (R + B.transpose() * Xs * B).inverse();
  out.K = M * B.transpose() * Xs * A;
  const Eigen::MatrixXd acl_t = (A - B * out.K).transpose();
  out.closed_loop_radius = acl_t.eigenvalues().cwiseAbs().maxCoeff();
  if (!(out.closed_loop_radius < 1.0)) return Error{"preview inverse: closed loop not stable", {}};
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(n, n);
  const Eigen::MatrixXd S = (I - acl_t).inverse();  // sum_j (A_cl')^j

  // Bellman with V_k(x) = x'X x - 2 x'g_k + c: v_k = -K x_k + M R r_{k+d} + M B' g_{k+1} and
  //   g_k = A_cl' g_{k+1} + C' r_k - K' R r_{k+d}, so
  //   g_{k+1} = sum_j (A_cl')^j [C' r_{k+1+j} - K' R r_{k+1+j+d}], references beyond r_{k+P}
  //   equal to r_{k+P} (the tail sums to (A_cl')^j S).
  std::vector<Eigen::MatrixXd> gs(static_cast<size_t>(P + 1), Eigen::MatrixXd::Zero(n, m));
  const Eigen::MatrixXd ct = C.transpose();
  const Eigen::MatrixXd ktr = out.K.transpose() * R;
  Eigen::MatrixXd pw = I;  // (A_cl')^j
  for (int j = 0; j < P; ++j) {
    const int a1 = 1 + j;
    if (a1 < P) gs[static_cast<size_t>(a1)] += pw * ct;
    else gs[static_cast<size_t>(P)] += pw * S * ct;
    const int a2 = 1 + j + ref_offset;
    if (a2 < P) gs[static_cast<size_t>(a2)] -= pw * ktr;
    else if (a2 == P) gs[static_cast<size_t>(P)] -= pw * S * ktr;
    pw = pw * acl_t;
  }
  out.F.assign(static_cast<size_t>(P + 1), Eigen::MatrixXd::Zero(m, m));
  for (int i = 1; i <= P; ++i) out.F[static_cast<size_t>(i)] = M * B.transpose() * gs[static_cast<size_t>(i)];
  out.F[static_cast<size_t>(ref_offset)] += M * R;

  Eigen::FullPivLU<Eigen::MatrixXd> lu(I - A);
  if (!lu.isInvertible()) return Error{"feedforward model has no finite static gain", {}};
  out.rest_state = lu.solve(B);
  return out;
}

}  // namespace feedloop::control
