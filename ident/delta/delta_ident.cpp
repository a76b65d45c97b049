// The delta identification procedure of Sect. IV (see delta_ident.hpp).
#include "ident/delta/delta_ident.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

#include "ident/delta/rational_fit.hpp"
#include "ident/frf.hpp"
#include "model/delta_kinematics.hpp"
#include "model/delta_lpv.hpp"
#include "model/frf_metrics.hpp"

namespace feedloop::ident::delta {

namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

Complex jw(double f_hz) { return {0.0, kTwoPi * f_hz}; }

// Pole pairs (upper half plane) of a fitted denominator, sorted by magnitude.
Result<std::vector<Complex>> pole_pairs(const model::TransferFunction& tf, size_t expected) {
  std::vector<Complex> up;
  for (const Complex& p : tf.poles())
    if (p.imag() > 0.0) up.push_back(p);
  if (up.size() != expected)
    return Error{"carriage fit: expected " + std::to_string(expected) + " lightly damped pole pairs, found " +
                     std::to_string(up.size()),
                 {}};
  for (const Complex& p : up)
    if (!(p.real() < 0.0)) return Error{"carriage fit: unstable fitted pole", {}};
  std::sort(up.begin(), up.end(), [](Complex a, Complex b) { return std::abs(a) < std::abs(b); });
  return up;
}

// Eq. 31-34 with the added-mass variant (Eq. 37-40) tied to the same k and c + b.
struct CarriageTheta {
  double wn, zeta, c_over_m, d0, d1, d2, wn_added;
  static constexpr int kSize = 7;
  // x = [ln wn, ln zeta, sqrt(c/m / 10), ln d0, d1 / 100, ln d2, ln wn']. c/m >= 0 by construction:
  // the zero -k/c (~23 krad/s) is seen only as a phase lead of c/k (~44 us) across the band, which
  // a measurement delay of the same size cancels (an encoder read 50 us late asks for c < 0); then
  // c ends at 0 and the delay is left in the fit's residual instead (docs/ident_delta.md).
  static CarriageTheta from(const Eigen::VectorXd& x) {
    return {std::exp(x[0]), std::exp(x[1]), 10.0 * x[2] * x[2], std::exp(x[3]),
            100.0 * x[4],   std::exp(x[5]), std::exp(x[6])};
  }
  Eigen::VectorXd to() const {
    Eigen::VectorXd x(kSize);
    x << std::log(wn), std::log(zeta), std::sqrt(std::max(c_over_m, 0.0) / 10.0), std::log(d0),
        d1 / 100.0, std::log(d2), std::log(wn_added);
    return x;
  }
  Complex electrical(Complex s) const { return (d1 * s + d0) / (s * s + d2 * s + d0); }
  Complex g(Complex s) const {  // Eq. 33 x Eq. 34
    return (c_over_m * s + wn * wn) / (s * s + 2.0 * zeta * wn * s + wn * wn) * electrical(s);
  }
  Complex g_added(Complex s) const {  // Eq. 38: c/m' = (c/m) wn'^2/wn^2, zeta' wn' = zeta wn m/m'
    const double r = wn_added * wn_added / (wn * wn);
    const double two_zw = 2.0 * zeta * wn * r;
    return (c_over_m * r * s + wn_added * wn_added) / (s * s + two_zw * s + wn_added * wn_added) * electrical(s);
  }
};

}  // namespace

Result<CarriageFit> identify_carriage(const DeltaMeasurements& meas) {
  const std::vector<double> f = meas.plan.carriage_grid.points_hz();
  if (meas.carriage.size() != f.size() || meas.carriage_added.size() != f.size())
    return Error{"carriage fit: measurements do not match the carriage grid", {}};
  CarriageFit out;
  // Eq. 42: 4th-order fits.
  RationalFitSpec spec;
  spec.num_order = 2;
  spec.den_order = 4;
  auto tf = fit_rational(f, meas.carriage, spec);
  if (!tf.ok()) return tf.error();
  auto tf_added = fit_rational(f, meas.carriage_added, spec);
  if (!tf_added.ok()) return tf_added.error();
  out.g_qd = *tf;
  out.g_qd_added = *tf_added;
  auto pp = pole_pairs(*tf, 2);
  if (!pp.ok()) return pp.error();
  auto pp_added = pole_pairs(*tf_added, 2);
  if (!pp_added.ok()) return pp_added.error();
  // The electrical pair stays put when mass is added; the mechanical one moves.
  auto nearest = [](Complex p, const std::vector<Complex>& others) {
    double d = 1e300;
    for (Complex o : others) d = std::min(d, std::abs(p - o) / std::abs(p));
    return d;
  };
  const int e_idx = nearest((*pp)[0], *pp_added) < nearest((*pp)[1], *pp_added) ? 0 : 1;
  const Complex pe = (*pp)[static_cast<size_t>(e_idx)], pm = (*pp)[static_cast<size_t>(1 - e_idx)];
  const int e_idx_added = std::abs((*pp_added)[0] - pe) < std::abs((*pp_added)[1] - pe) ? 0 : 1;
  const Complex pm_added = (*pp_added)[static_cast<size_t>(1 - e_idx_added)];
  if (!(std::abs(pm_added) < std::abs(pm)))
    return Error{"carriage fit: the added mass did not lower the mechanical mode", {}};

  // Initial guess from the poles and the numerator (g2 s^2 + g1 s + g0 = (c/m s + wn^2)(d1 s + d0),
  // up to the fit's gain).
  CarriageTheta th{};
  th.wn = std::abs(pm);
  th.zeta = -pm.real() / th.wn;
  th.d0 = std::norm(pe);
  th.d2 = -2.0 * pe.real();
  th.wn_added = std::abs(pm_added);
  {
    const double g2 = tf->num[0], g1 = tf->num[1];
    double a = 0.0, d1 = g1 / (th.wn * th.wn);
    for (int it = 0; it < 5; ++it) {
      a = std::abs(d1) > 1e-12 ? g2 / d1 : 0.0;
      if (!(a > 0.0)) a = 1.0;
      d1 = (g1 - a * th.d0) / (th.wn * th.wn);
    }
    th.c_over_m = a;
    th.d1 = d1;
  }
  // Structured least squares on both FRFs: residual log(G_fit / G_meas) (relative magnitude and
  // phase error alike).
  const auto n = static_cast<int>(f.size());
  ResidualFn res = [&](const Eigen::VectorXd& x, Eigen::VectorXd& r) {
    const CarriageTheta t = CarriageTheta::from(x);
    for (int k = 0; k < n; ++k) {
      const auto ku = static_cast<size_t>(k);
      const Complex s = jw(f[ku]);
      const Complex e1 = std::log(t.g(s) / meas.carriage[ku]);
      const Complex e2 = std::log(t.g_added(s) / meas.carriage_added[ku]);
      r[4 * k] = e1.real();
      r[4 * k + 1] = e1.imag();
      r[4 * k + 2] = e2.real();
      r[4 * k + 3] = e2.imag();
    }
  };
  auto sol = levenberg_marquardt(res, 4 * n, th.to());
  if (!sol.ok()) return Error{"carriage fit: " + sol.error().message, {}};
  const CarriageTheta t = CarriageTheta::from(sol->x);
  double sum = 0.0;
  for (int k = 0; k < n; ++k) {
    const auto ku = static_cast<size_t>(k);
    sum += std::norm(t.g(jw(f[ku])) / meas.carriage[ku] - 1.0) + std::norm(t.g_added(jw(f[ku])) / meas.carriage_added[ku] - 1.0);
  }
  out.rms_rel = std::sqrt(sum / (2.0 * n));
  out.omega_n_rad_s = t.wn;
  out.zeta = t.zeta;
  out.omega_n_added_rad_s = t.wn_added;
  out.zeta_added = t.zeta * t.wn_added / t.wn;
  if (!(t.wn > t.wn_added)) return Error{"carriage fit: omega_n' >= omega_n, cannot apply Eq. 41", {}};
  out.m_kg = t.wn_added * t.wn_added / (t.wn * t.wn - t.wn_added * t.wn_added) * meas.plan.m_add_kg;  // Eq. 41
  out.k_n_m = out.m_kg * t.wn * t.wn;                                                                   // Eq. 36
  const double cb = 2.0 * t.zeta * t.wn * out.m_kg;                                                     // Eq. 35
  out.c_n_s_m = t.c_over_m * out.m_kg;                                                                  // Eq. 33
  out.b_n_s_m = cb - out.c_n_s_m;
  out.m_c_kg = out.m_kg - 0.5 * meas.m_f_kg;  // Eq. 30
  out.d0_per_s2 = t.d0;
  out.d1_per_s = t.d1;
  out.d2_per_s = t.d2;
  return out;
}

Result<EffectorFit> identify_effector(const DeltaMeasurements& meas) {
  const std::vector<double> f = meas.plan.hammer_grid.points_hz();
  if (meas.hammer.size() != f.size()) return Error{"effector fit: measurement does not match the hammer grid", {}};
  RationalFitSpec spec;
  spec.num_order = 2;
  spec.den_order = 2;
  auto tf = fit_rational(f, meas.hammer, spec);  // Eq. 46
  if (!tf.ok()) return Error{"effector fit: " + tf.error().message, {}};
  const double u2 = tf->num[0], u0 = tf->num[2], v0 = tf->den[2];
  if (!(u0 / u2 > 0.0) || !(v0 > 0.0)) return Error{"effector fit: no two-mass zero/pole pair in the hammer FRF", {}};
  EffectorFit out;
  out.omega_z_rad_s = std::sqrt(u0 / u2);  // Eq. 47
  out.omega_p_rad_s = std::sqrt(v0);       // Eq. 48
  if (!(out.omega_z_rad_s < out.omega_p_rad_s)) return Error{"effector fit: zero above the pole (not a two-mass FRF)", {}};
  out.m1_kg = out.omega_z_rad_s * out.omega_z_rad_s / v0 * meas.m_tot_kg;  // Eq. 49
  out.m2_kg = meas.m_tot_kg - out.m1_kg;
  double sum = 0.0;
  for (size_t k = 0; k < f.size(); ++k) sum += std::norm(tf->at_hz(f[k]) / meas.hammer[k] - 1.0);
  out.rms_rel = std::sqrt(sum / static_cast<double>(f.size()));
  return out;
}

Result<CouplingFit> identify_coupling(const DeltaMeasurements& meas, const model::DeltaParams& base,
                                      model::ForceTransform form, bool free_mass_scale) {
  const std::vector<double> f = meas.plan.centre_grid.points_hz();
  if (meas.centre_task.size() != f.size()) return Error{"coupling fit: measurements do not match the centre grid", {}};
  const auto n = static_cast<int>(f.size());
  auto jbar = model::jacobian(base.geometry, meas.plan.centre_mm);
  if (!jbar.ok()) return jbar.error();
  const Eigen::Matrix3d jinv = jbar->inverse();
  // Each frequency's errors are scaled by the norm of the measured 3x3 matrix there: relative
  // error over the whole range without letting near-zero entries (antiresonances, the y column
  // of carriage A) dominate.
  std::vector<double> scale(f.size());
  for (size_t k = 0; k < f.size(); ++k) scale[k] = std::max(meas.centre_task[k].norm(), 1e-300);

  // x = [ln b_x, ln b_y, ln b_z, ln k_x, ln k_y, ln k_z (, ln mass scale)].
  auto params_of = [&](const Eigen::VectorXd& x) {
    model::DeltaParams p = base;
    if (x.size() > 6) {
      p.m1_kg *= std::exp(x[6]);
      p.m2_kg *= std::exp(x[6]);
    }
    p.b_x_n_s_m = std::exp(x[0]);
    p.b_y_n_s_m = std::exp(x[1]);
    p.b_z_n_s_m = std::exp(x[2]);
    p.k_x_n_m = std::exp(x[3]);
    p.k_y_n_m = std::exp(x[4]);
    p.k_z_n_m = std::exp(x[5]);
    return p;
  };
  // Residual of column j (or all columns when j < 0): (H_pred - H_meas) / ||H_meas||.
  auto residual = [&](const Eigen::VectorXd& x, Eigen::VectorXd& r, int only_axis) -> bool {
    auto model = model::DeltaLpvModel::create(params_of(x), form);
    if (!model.ok()) return false;
    auto op = model->at(meas.plan.centre_mm);
    if (!op.ok()) return false;
    int idx = 0;
    for (int k = 0; k < n; ++k) {
      const auto ku = static_cast<size_t>(k);
      const Eigen::Matrix3cd h = model->frf(*op, jw(f[ku])) * jinv;
      for (int j = 0; j < 3; ++j) {
        if (only_axis >= 0 && j != only_axis) continue;
        const Eigen::Vector3cd e = (h.col(j) - meas.centre_task[ku].col(j)) / scale[ku];
        for (int i = 0; i < 3; ++i) {
          r[idx++] = e[i].real();
          r[idx++] = e[i].imag();
        }
      }
    }
    return true;
  };
  const double m2 = base.m2_kg > 0.0 ? base.m2_kg : 1e-3;
  // Initial guess: start every axis at a 50 Hz m2 mode (k_j = m2 w^2, b_j = 2 zeta m2 w,
  // zeta 0.05); then per axis a log grid over the mode (3-600 Hz, three damping ratios) with the
  // other axes fixed, twice over.
  Eigen::VectorXd x(6);
  for (int j = 0; j < 3; ++j) {
    const double w = kTwoPi * 50.0;
    x[3 + j] = std::log(m2 * w * w);
    x[j] = std::log(2.0 * 0.05 * m2 * w);
  }
  Eigen::VectorXd r_axis(6 * n);
  for (int pass = 0; pass < 2; ++pass) {
    for (int j = 0; j < 3; ++j) {
      double best = 1e300;
      Eigen::VectorXd best_x = x;
      for (int g = 0; g <= 40; ++g) {
        const double w = kTwoPi * 3.0 * std::pow(600.0 / 3.0, g / 40.0);
        for (double zeta : {0.02, 0.1, 0.4}) {
          Eigen::VectorXd xt = x;
          xt[3 + j] = std::log(m2 * w * w);
          xt[j] = std::log(2.0 * zeta * m2 * w);
          if (!residual(xt, r_axis, j)) continue;
          const double c = r_axis.squaredNorm();
          if (c < best) {
            best = c;
            best_x = xt;
          }
        }
      }
      x = best_x;
    }
  }
  ResidualFn res = [&](const Eigen::VectorXd& xx, Eigen::VectorXd& r) {
    if (!residual(xx, r, -1)) r.setConstant(1e10);
  };
  if (free_mass_scale) {
    x.conservativeResize(7);
    x[6] = 0.0;
  }
  auto sol = levenberg_marquardt(res, 18 * n, x);
  if (!sol.ok()) return Error{"coupling fit: " + sol.error().message, {}};
  CouplingFit out;
  const model::DeltaParams p = params_of(sol->x);
  out.b_n_s_m = {p.b_x_n_s_m, p.b_y_n_s_m, p.b_z_n_s_m};
  out.k_n_m = {p.k_x_n_m, p.k_y_n_m, p.k_z_n_m};
  out.mass_scale = free_mass_scale ? std::exp(sol->x[6]) : 1.0;
  // RMS over frequencies of ||H_pred - H_meas|| / ||H_meas|| (18 residuals per frequency).
  out.rms_rel = sol->rms * std::sqrt(18.0);
  out.evaluations = sol->evaluations;
  return out;
}

Result<CouplingFit> identify_coupling_eq68(const DeltaMeasurements& meas, const model::DeltaParams& base,
                                           model::ForceTransform form, Eq68Alpha alpha_kind) {
  const std::vector<double> f = meas.plan.centre_grid.points_hz();
  if (meas.centre_task.size() != f.size()) return Error{"Eq. 68 fit: measurements do not match the centre grid", {}};
  auto model0 = model::DeltaLpvModel::create(base, form);
  if (!model0.ok()) return model0.error();
  auto op = model0->at(meas.plan.centre_mm);
  if (!op.ok()) return op.error();
  const Eigen::Matrix3d jinv0 = op->jbar.inverse();  // q = Jbar^-1 X
  // Eq. 69: alpha_ji = T(i, j), force on carriage i per unit of w_j X_j. PerCarriageMotion divides
  // by q_i / X_j so that the force is per unit of carriage i's own motion, which is what Eq. 68's
  // single-carriage polynomial assumes.
  Eigen::Matrix3d alpha = op->transform;
  if (alpha_kind == Eq68Alpha::PerCarriageMotion) alpha = alpha.cwiseQuotient(jinv0);
  const double m = base.m_kg(), cb = base.c_n_s_m + base.b_n_s_m, k = base.k_n_m;
  const double m1 = base.m1_effective_kg(), m2 = base.m2_kg;
  if (!(m2 > 0.0)) return Error{"Eq. 68 fit: needs a two-mass effector (m2 > 0)", {}};
  RationalFitSpec spec;
  spec.num_order = 3;  // Eq. 66
  spec.den_order = 4;
  CouplingFit out;
  for (int j = 0; j < 3; ++j) {
    // Rows of the linear least squares in (b_j, k_j), each scaled to unit norm.
    std::vector<Eigen::RowVector2d> rows;
    std::vector<double> rhs;
    for (int i = 0; i < 3; ++i) {
      // Carriage i does not move (or feel a force) when the effector moves along j: skip.
      if (std::abs(jinv0(i, j)) < 0.05 * jinv0.col(j).cwiseAbs().maxCoeff()) continue;
      if (std::abs(op->transform(i, j)) < 0.05 * op->transform.col(j).cwiseAbs().maxCoeff()) continue;
      const double a = alpha(i, j);
      // Mechanical part of the measured FRF: the electrical factor G_qd,e (Eq. 34) is common to
      // every entry of Eq. 29 and is divided out with the identified d0-d2.
      std::vector<Complex> hm(f.size());
      for (size_t kf = 0; kf < f.size(); ++kf) {
        const Complex s = jw(f[kf]);
        hm[kf] = meas.centre_task[kf](i, j) / ((base.d1_per_s * s + base.d0_per_s2) /
                                              (s * s + base.d2_per_s * s + base.d0_per_s2));
      }
      auto tf = fit_rational(f, hm, spec);
      if (!tf.ok()) return Error{"Eq. 66 fit: " + tf.error().message, {}};
      const double lead = (m + a * m1) * m2;
      const double a3 = tf->den[1] * lead, a2 = tf->den[2] * lead, a1 = tf->den[3] * lead, a0 = tf->den[4] * lead;
      const double ma = m + a * (m1 + m2);
      // Eq. 68 (as expanded: the s^2 term has (c+b) b_j, see model/delta_submodels.hpp).
      const Eigen::RowVector2d r3(ma, 0.0), r2(cb, ma), r1(k, cb), r0(0.0, k);
      const double y3 = a3 - m2 * cb, y2 = a2 - m2 * k, y1 = a1, y0 = a0;
      for (const auto& [row, y] : {std::pair{r3, y3}, std::pair{r2, y2}, std::pair{r1, y1}, std::pair{r0, y0}}) {
        const double nrm = row.norm();
        rows.push_back(row / nrm);
        rhs.push_back(y / nrm);
      }
    }
    if (rows.empty()) return Error{"Eq. 68 fit: no carriage sees axis " + std::to_string(j), {}};
    Eigen::MatrixXd a(static_cast<Eigen::Index>(rows.size()), 2);
    Eigen::VectorXd y(static_cast<Eigen::Index>(rows.size()));
    for (size_t r = 0; r < rows.size(); ++r) {
      a.row(static_cast<Eigen::Index>(r)) = rows[r];
      y[static_cast<Eigen::Index>(r)] = rhs[r];
    }
    // Columns on comparable scales (b ~ 10, k ~ 1e4) before solving.
    const Eigen::Vector2d col = a.colwise().norm().transpose();
    const Eigen::Vector2d sol = (a * col.cwiseInverse().asDiagonal()).colPivHouseholderQr().solve(y).cwiseQuotient(col);
    out.b_n_s_m[j] = sol[0];
    out.k_n_m[j] = sol[1];
  }
  out.physical = out.b_n_s_m.allFinite() && out.k_n_m.allFinite() && out.b_n_s_m.minCoeff() > 0.0 &&
                 out.k_n_m.minCoeff() > 0.0;
  if (!out.physical) {
    out.rms_rel = std::numeric_limits<double>::infinity();
    return out;
  }
  // Score it like the Eq. 29 least squares.
  model::DeltaParams p = base;
  p.b_x_n_s_m = out.b_n_s_m.x();
  p.b_y_n_s_m = out.b_n_s_m.y();
  p.b_z_n_s_m = out.b_n_s_m.z();
  p.k_x_n_m = out.k_n_m.x();
  p.k_y_n_m = out.k_n_m.y();
  p.k_z_n_m = out.k_n_m.z();
  auto model = model::DeltaLpvModel::create(p, form);
  if (!model.ok()) return model.error();
  auto op2 = model->at(meas.plan.centre_mm);
  if (!op2.ok()) return op2.error();
  const Eigen::Matrix3d jinv = op2->jbar.inverse();
  double sum = 0.0;
  for (size_t kf = 0; kf < f.size(); ++kf) {
    const Eigen::Matrix3cd h = model->frf(*op2, jw(f[kf])) * jinv;
    sum += (h - meas.centre_task[kf]).squaredNorm() / meas.centre_task[kf].squaredNorm();
  }
  out.rms_rel = std::sqrt(sum / static_cast<double>(f.size()));
  return out;
}

Result<DeltaIdentification> identify(const DeltaMeasurements& meas, model::ForceTransform form) {
  DeltaIdentification id;
  id.form = form;
  auto carriage = identify_carriage(meas);
  if (!carriage.ok()) return carriage.error();
  auto effector = identify_effector(meas);
  if (!effector.ok()) return effector.error();
  id.carriage = *carriage;
  id.effector = *effector;
  model::DeltaParams p = meas.cad;  // delta, D_e, geometry from the CAD model
  p.m_f_kg = meas.m_f_kg;
  p.m_c_kg = carriage->m_c_kg;
  p.c_n_s_m = carriage->c_n_s_m;
  p.b_n_s_m = carriage->b_n_s_m;
  p.k_n_m = carriage->k_n_m;
  p.d0_per_s2 = carriage->d0_per_s2;
  p.d1_per_s = carriage->d1_per_s;
  p.d2_per_s = carriage->d2_per_s;
  // The hammer weighs the effector as it is; m1 in DeltaParams excludes the forearm halves when
  // the CAD model puts them on m1.
  p.m1_kg = effector->m1_kg - (p.forearm_half_mass_on_m1 ? 1.5 * meas.m_f_kg : 0.0);
  p.m2_kg = effector->m2_kg;
  if (Status s = model::validate(p); !s) {
    // b_j, k_j are still the defaults here; only the identified fields can be at fault.
    return Error{"identified sub-model parameters are invalid: " + s.error().message, {}};
  }
  auto coupling = identify_coupling(meas, p, form, false);
  if (!coupling.ok()) return coupling.error();
  id.coupling = *coupling;
  p.b_x_n_s_m = coupling->b_n_s_m.x();
  p.b_y_n_s_m = coupling->b_n_s_m.y();
  p.b_z_n_s_m = coupling->b_n_s_m.z();
  p.k_x_n_m = coupling->k_n_m.x();
  p.k_y_n_m = coupling->k_n_m.y();
  p.k_z_n_m = coupling->k_n_m.z();
  id.params = p;
  return id;
}

Result<ValidationTables> validate(const DeltaMeasurements& meas, const model::DeltaParams& params,
                                  model::ForceTransform form) {
  auto model = model::DeltaLpvModel::create(params, form);
  if (!model.ok()) return model.error();
  ValidationTables t;
  for (int p = 0; p < 4; ++p) {
    const Eigen::Vector3d pos = p == 0 ? meas.plan.centre_mm : meas.plan.validation_mm[static_cast<size_t>(p - 1)];
    const model::FrfSet& measured = p == 0 ? meas.centre : meas.validation[static_cast<size_t>(p - 1)];
    auto predicted = model->frf(pos, meas.plan.validation_grid);
    if (!predicted.ok()) return predicted.error();
    auto am = model::mu_acc(measured, *predicted, model::FrfQuantity::Magnitude);
    auto ap = model::mu_acc(measured, *predicted, model::FrfQuantity::Phase);
    if (!am.ok()) return am.error();
    if (!ap.ok()) return ap.error();
    for (int i = 0; i < 3; ++i) {
      t.acc_mag_pct(i, p) = (*am)(i, i);
      t.acc_phase_pct(i, p) = (*ap)(i, i);
    }
    if (p == 0) continue;
    auto rm = model::error_reduction_pct(measured, *predicted, meas.centre, model::FrfQuantity::Magnitude);
    auto rp = model::error_reduction_pct(measured, *predicted, meas.centre, model::FrfQuantity::Phase);
    if (!rm.ok()) return rm.error();
    if (!rp.ok()) return rp.error();
    for (int i = 0; i < 3; ++i) {
      t.reduction_mag_pct(i, p - 1) = (*rm)(i, i);
      t.reduction_phase_pct(i, p - 1) = (*rp)(i, i);
    }
  }
  t.avg_acc_mag_pct = t.acc_mag_pct.rowwise().mean();
  t.avg_acc_phase_pct = t.acc_phase_pct.rowwise().mean();
  return t;
}

}  // namespace feedloop::ident::delta
