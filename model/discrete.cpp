// ZOH discretisation and the RT-safe discrete filter (see discrete.hpp).
#include "model/discrete.hpp"

#include <cmath>    // std::isfinite
#include <numbers>  // std::numbers::pi

#include <unsupported/Eigen/MatrixFunctions>  // MatrixBase::exp

namespace feedloop::model {

Result<DiscreteStateSpace> discretize_zoh(const StateSpace& sys, double period_s) {
  if (!(period_s > 0.0) || !std::isfinite(period_s))
    return Error{"discretisation period must be positive and finite", {}};
  if (Status st = check_dimensions(sys); !st) return st.error();
  const int n = sys.states();
  const int m = sys.inputs();
  Eigen::MatrixXd aug = Eigen::MatrixXd::Zero(n + m, n + m);
  aug.topLeftCorner(n, n) = sys.A * period_s;
  aug.topRightCorner(n, m) = sys.B * period_s;
  const Eigen::MatrixXd e = aug.exp();
  DiscreteStateSpace d;
  d.Ad = e.topLeftCorner(n, n);
  d.Bd = e.topRightCorner(n, m);
  d.C = sys.C;
  d.D = sys.D;
  d.period_s = period_s;
  if (!d.Ad.allFinite() || !d.Bd.allFinite())
    return Error{"matrix exponential overflowed: the model is too fast or unstable for this period", {}};
  return d;
}

Eigen::MatrixXcd frequency_response(const DiscreteStateSpace& sys, double freq_hz) {
  using C = std::complex<double>;
  const C z = std::exp(C(0.0, 2.0 * std::numbers::pi * freq_hz * sys.period_s));
  Eigen::MatrixXcd zIA = -sys.Ad.cast<C>();
  zIA.diagonal().array() += z;
  return sys.C.cast<C>() * zIA.partialPivLu().solve(sys.Bd.cast<C>()) + sys.D.cast<C>();
}

Result<Eigen::MatrixXd> dc_gain(const DiscreteStateSpace& sys) {
  const Eigen::MatrixXd ia = Eigen::MatrixXd::Identity(sys.states(), sys.states()) - sys.Ad;
  Eigen::FullPivLU<Eigen::MatrixXd> lu(ia);
  if (!lu.isInvertible()) return Error{"Ad has an eigenvalue at 1 (integrator): no finite static gain", {}};
  return Eigen::MatrixXd(sys.D + sys.C * lu.solve(sys.Bd));
}

Status DiscreteLtiFilter::configure(const DiscreteStateSpace& sys) {
  if (Status st = check_dimensions(StateSpace{sys.Ad, sys.Bd, sys.C, sys.D}); !st) return st;
  sys_ = sys;
  x_ = Eigen::VectorXd::Zero(sys.states());
  x_next_ = Eigen::VectorXd::Zero(sys.states());
  const Eigen::MatrixXd ia = Eigen::MatrixXd::Identity(sys.states(), sys.states()) - sys.Ad;
  Eigen::FullPivLU<Eigen::MatrixXd> lu(ia);
  steady_state_map_ = lu.isInvertible() ? Eigen::MatrixXd(lu.solve(sys.Bd))
                                        : Eigen::MatrixXd::Zero(sys.states(), sys.inputs());
  return {};
}

void DiscreteLtiFilter::reset() { x_.setZero(); }

void DiscreteLtiFilter::reset_to_steady_state(const double* u) {
  const Eigen::Map<const Eigen::VectorXd> uv(u, sys_.inputs());
  x_.noalias() = steady_state_map_ * uv;
}

void DiscreteLtiFilter::step(const double* u, double* y) {
  const Eigen::Map<const Eigen::VectorXd> uv(u, sys_.inputs());
  Eigen::Map<Eigen::VectorXd> yv(y, sys_.outputs());
  yv.noalias() = sys_.C * x_;
  yv.noalias() += sys_.D * uv;
  x_next_.noalias() = sys_.Ad * x_;
  x_next_.noalias() += sys_.Bd * uv;
  x_.swap(x_next_);
}

}  // namespace feedloop::model
