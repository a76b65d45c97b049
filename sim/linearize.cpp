// Finite-difference linearisation and frequency response (see linearize.hpp).
#include "sim/linearize.hpp"

#include <algorithm>  // max
#include <cmath>      // ceil

#include <Eigen/Eigenvalues>

namespace feedloop::sim {

LinearModel linearize_dynamics(const Dynamics& f, const Eigen::VectorXd& x0, const Eigen::VectorXd& u0,
                               const Eigen::VectorXd& dx, double du, const Eigen::MatrixXd& c) {
  const Eigen::Index n = x0.size();
  const Eigen::Index m = u0.size();
  LinearModel lin{Eigen::MatrixXd(n, n), Eigen::MatrixXd(n, m), c};
  for (Eigen::Index i = 0; i < n; ++i) {
    Eigen::VectorXd xp = x0, xm = x0;
    xp[i] += dx[i];
    xm[i] -= dx[i];
    lin.a.col(i) = (f(xp, u0) - f(xm, u0)) / (2.0 * dx[i]);
  }
  for (Eigen::Index j = 0; j < m; ++j) {
    Eigen::VectorXd up = u0, um = u0;
    up[j] += du;
    um[j] -= du;
    lin.b.col(j) = (f(x0, up) - f(x0, um)) / (2.0 * du);
  }
  return lin;
}

Eigen::MatrixXcd frequency_response(const LinearModel& m, double freq_hz) {
  const std::complex<double> jw(0.0, 2.0 * 3.14159265358979323846 * freq_hz);
  Eigen::MatrixXcd sys = -m.a.cast<std::complex<double>>();
  sys.diagonal().array() += jw;
  const Eigen::MatrixXcd x = sys.partialPivLu().solve(m.b.cast<std::complex<double>>());
  return m.c.cast<std::complex<double>>() * x;
}

double fastest_mode_rad_s(const Eigen::MatrixXd& a) {
  const Eigen::VectorXcd ev = Eigen::EigenSolver<Eigen::MatrixXd>(a, false).eigenvalues();
  double w = 0.0;
  for (Eigen::Index i = 0; i < ev.size(); ++i) w = std::max(w, std::abs(ev[i]));
  return w;
}

double substep_hz_for(double omega_max_rad_s) {
  return std::max(1.0, std::ceil(omega_max_rad_s / kRk4HOmegaMax / 1000.0)) * 1000.0;
}

}  // namespace feedloop::sim
