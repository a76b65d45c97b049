// Test support for the model-based feedforward tests: planned trapezoid moves, and a simulation
// of the LINEAR model (gantry Eq. 15 or delta Eq. 29) at a step 20x finer than the servo period,
// re-linearised at the current position every period (the LPV model's own simulation), with the
// command moved linearly between period targets (what the feedforward was designed for).
#pragma once

#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>

#include <Eigen/Dense>

#include "control/feedforward.hpp"
#include "model/discrete.hpp"
#include "model/lti.hpp"

namespace feedloop::control::fftest {

// Rest-to-rest trapezoid from p0 to p1 (mm), starting at t0_s.
struct Trapezoid {
  double p0_mm, p1_mm, v_mm_s, a_mm_s2, t0_s;
  double duration_s() const {
    const double d = std::abs(p1_mm - p0_mm);
    const double v = std::min(v_mm_s, std::sqrt(d * a_mm_s2));
    return v / a_mm_s2 * 2.0 + (d - v * v / a_mm_s2) / v;
  }
  double at(double t_s) const {
    const double d = std::abs(p1_mm - p0_mm), sgn = p1_mm >= p0_mm ? 1.0 : -1.0;
    const double v = std::min(v_mm_s, std::sqrt(d * a_mm_s2));
    const double ta = v / a_mm_s2, tc = (d - v * v / a_mm_s2) / v;
    double t = t_s - t0_s, s;
    if (t <= 0) s = 0;
    else if (t < ta) s = 0.5 * a_mm_s2 * t * t;
    else if (t < ta + tc) s = 0.5 * v * ta + v * (t - ta);
    else if (t < 2 * ta + tc) {
      const double td = 2 * ta + tc - t;
      s = d - 0.5 * a_mm_s2 * td * td;
    } else s = d;
    return p0_mm + sgn * s;
  }
};

// Continuous model at a position given by the current output (mm); SI state space with m inputs,
// static gain I.
using ModelAt = std::function<model::StateSpace(const Eigen::VectorXd& y_mm)>;

// Plant simulation of the LPV model about its current operating point: the state is the deviation
// x~ = x - x_rest(u) from the rest state of the current command (x_rest = -A^-1 B u depends on the
// operating point, e.g. the delta effector's X2 = Jbar q), so
//   x~' = A(p) x~ + A(p)^-1 B(p) u',   y = u + C x~.
// advance(u_k) moves the command linearly from u_{k-1} (at t_{k-1}) to u_k (at t_k), so u' is
// constant over the period, and returns y at t_k. A(p), B(p) are taken at the output at t_{k-1}.
class FineSim {
 public:
  FineSim(ModelAt model, double period_s, int substeps = 20) : model_(std::move(model)), T_(period_s), n_sub_(substeps) {}
  void reset(const Eigen::VectorXd& u_mm) {
    const model::StateSpace ss = model_(u_mm);
    x_ = Eigen::VectorXd::Zero(ss.states());
    u_ = u_mm;
    y_ = u_mm;
  }
  Eigen::VectorXd advance(const Eigen::VectorXd& u_next_mm) {
    const model::StateSpace ss = model_(y_);
    model::StateSpace dev = ss;
    dev.B = ss.A.partialPivLu().solve(ss.B);
    const auto d = model::discretize_zoh(dev, T_ / n_sub_);
    const Eigen::VectorXd udot = (u_next_mm - u_) / T_;
    for (int i = 0; i < n_sub_; ++i) x_ = d->Ad * x_ + d->Bd * udot;
    u_ = u_next_mm;
    y_ = u_ + ss.C * x_;
    return y_;
  }

 private:
  ModelAt model_;
  double T_;
  int n_sub_;
  Eigen::VectorXd x_, u_, y_;
};

struct TrackingError {
  double max_um = 0, rms_um = 0;
  double max_abs_u_minus_r_mm = 0;  // how far the command strays from the reference
  double final_u_minus_r_mm = 0;    // at the end (settled?)
};

// Runs `ff` (nullptr: u = r) over the references r_mm(k), nozzle(k) for k = 0..n-1 (period T),
// on the plant `sim`, and returns the error y_k - r_k over the joints 0..joints-1.
inline TrackingError run(Feedforward* ff, FineSim& sim, int joints, int n,
                         const std::function<FeedforwardInput(int k)>& plan) {
  const int P = ff ? ff->preview_samples() : 0;
  FeedforwardInput in0 = plan(0);
  if (ff) ff->reset(in0);
  Eigen::VectorXd u(joints);
  for (int j = 0; j < joints; ++j) u[j] = in0.r_mm[static_cast<size_t>(j)];
  sim.reset(u);
  TrackingError e;
  double sum2 = 0;
  JointArray uk{};
  for (int k = 0; k < n; ++k) {
    const FeedforwardInput in = plan(k + P);
    if (ff) ff->step(in, uk);
    else uk = in.r_mm;
    const FeedforwardInput now = plan(k);
    for (int j = 0; j < joints; ++j) u[j] = uk[static_cast<size_t>(j)];
    const Eigen::VectorXd y = sim.advance(u);  // y at t_k
    for (int j = 0; j < joints; ++j) {
      const double err = (y[j] - now.r_mm[static_cast<size_t>(j)]) * 1e3;
      e.max_um = std::max(e.max_um, std::abs(err));
      sum2 += err * err;
      const double dev = uk[static_cast<size_t>(j)] - now.r_mm[static_cast<size_t>(j)];
      e.max_abs_u_minus_r_mm = std::max(e.max_abs_u_minus_r_mm, std::abs(dev));
      if (k == n - 1) e.final_u_minus_r_mm = std::max(e.final_u_minus_r_mm, std::abs(dev));
    }
  }
  e.rms_um = std::sqrt(sum2 / (static_cast<double>(n) * joints));
  return e;
}

}  // namespace feedloop::control::fftest
