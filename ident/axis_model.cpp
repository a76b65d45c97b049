// Simulation of the identification's axis model (see axis_model.hpp).
#include "ident/axis_model.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>
#include <unsupported/Eigen/MatrixFunctions>

#include "model/gantry_axis.hpp"
#include "model/lead_lag.hpp"

namespace feedloop::ident {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kSubsteps = 5;
constexpr int kCrossingSplit = 8;

using Mat6 = Eigen::Matrix<double, 6, 6>;
using Mat63 = Eigen::Matrix<double, 6, 3>;
using Vec6 = Eigen::Matrix<double, 6, 1>;

}  // namespace

const char* effect_name(Effect e) {
  switch (e) {
    case Effect::kPeriodicPosition: return "periodic_position";
    case Effect::kCoulombFriction: return "coulomb_friction";
    case Effect::kBacklash: return "backlash";
    case Effect::kDirectionStiffness: return "direction_dependent_stiffness";
    case Effect::kExtraResonance: return "extra_resonance";
    case Effect::kTimeDelay: return "time_delay";
    case Effect::kScaleError: return "scale_error";
  }
  return "?";
}

double AxisModel::periodic_amplitude_um() const { return std::hypot(periodic_sin_um, periodic_cos_um); }

AxisModel preset_axis_model(const std::string& axis_name) {
  AxisModel m;
  if (axis_name == "y" || axis_name == "Y") {
    m.m2_kg = 1.07;
    m.k1_n_m = 390747.0;
    m.k2_n_m = 19814.0;
    m.c1_n_s_m = 409.95;
    m.c2_n_s_m = 71.7733;
  }
  return m;
}

void eq17_coefficients(const AxisModel& m, double psi[4]) {
  // Eq. 16 divided by m1 m2 (e = 1).
  const double a4 = m.m1_kg * m.m2_kg;
  psi[0] = (m.c1_n_s_m * m.m2_kg + m.c2_n_s_m * m.m1_kg) / a4;
  psi[1] = (m.c1_n_s_m * m.c2_n_s_m + (m.k1_n_m + m.k2_n_m) * m.m2_kg + m.k2_n_m * m.m1_kg) / a4;
  psi[2] = (m.c1_n_s_m * m.k2_n_m + m.c2_n_s_m * (m.k1_n_m + m.k2_n_m)) / a4;
  psi[3] = m.k1_n_m * m.k2_n_m / a4;
}

namespace {

// Continuous linear part: q = [x1, v1, x2, v2, x3, v3], inputs [u, F_rotor, F_carriage] (Eq. 13),
// the nominal belt k2 (x1 - x2) included; x3, v3 the extra resonance's mass (decaying dummies
// when it is off).
void linear_part(const AxisModel& m, Mat6* A_out, Mat63* B_out) {
  Mat6& A = *A_out;
  Mat63& B = *B_out;
  A.setZero();
  B.setZero();
  const double k2 = m.k2_n_m;
  A(0, 1) = 1.0;
  A(1, 0) = -(m.k1_n_m) / m.m1_kg;
  A(1, 1) = -m.c1_n_s_m / m.m1_kg;
  A(2, 3) = 1.0;
  A(3, 3) = -m.c2_n_s_m / m.m2_kg;
  A(4, 5) = 1.0;
  B(1, 0) = m.k1_n_m / m.m1_kg;
  B(1, 1) = 1.0 / m.m1_kg;
  B(3, 2) = 1.0 / m.m2_kg;
  A(1, 0) -= k2 / m.m1_kg;
  A(1, 2) += k2 / m.m1_kg;
  A(3, 0) += k2 / m.m2_kg;
  A(3, 2) -= k2 / m.m2_kg;
  if (m.has(Effect::kExtraResonance)) {
    const double w = 2.0 * kPi * std::max(m.extra_freq_hz, 1e-3);
    const double m3 = std::max(m.extra_mass_kg, 1e-6);
    const double k3 = m3 * w * w, c3 = 2.0 * std::max(m.extra_damping, 0.0) * m3 * w;
    // Mount force on the carriage: k3 (x3 - x2) + c3 (v3 - v2); the opposite on the mass.
    A(3, 2) -= k3 / m.m2_kg;
    A(3, 3) -= c3 / m.m2_kg;
    A(3, 4) += k3 / m.m2_kg;
    A(3, 5) += c3 / m.m2_kg;
    A(5, 4) = -k3 / m3;
    A(5, 5) = -c3 / m3;
    A(5, 2) = k3 / m3;
    A(5, 3) = c3 / m3;
  } else {
    A(4, 4) = -1.0;
    A(5, 5) = -1.0;
  }
}

// sin and cos of phi0 + d from sin/cos of phi0: Taylor series of sin d, cos d (error below
// 1e-13 for |d| <= 0.05 rad), the exact sincos otherwise. The runout phase moves by far less than
// that within a sample, so the exact sincos is needed once per sample instead of once per substep.
inline void sincos_near(double s0, double c0, double d, double* s, double* c) {
  if (std::abs(d) > 0.05) {
    const double phi = std::atan2(s0, c0) + d;
    *s = std::sin(phi);
    *c = std::cos(phi);
    return;
  }
  const double d2 = d * d;
  const double sd = d * (1.0 - d2 / 6.0 * (1.0 - d2 / 20.0 * (1.0 - d2 / 42.0)));
  const double cd = 1.0 - d2 / 2.0 * (1.0 - d2 / 12.0 * (1.0 - d2 / 30.0));
  *s = s0 * cd + c0 * sd;
  *c = c0 * cd - s0 * sd;
}

// The time loop on N states (4 without the extra resonance, 6 with it): x2 (mm) per sample.
template <int N>
void run_states(const AxisModel& m, const Mat6& A, const Mat63& B, const std::vector<double>& u_mm, double period_s,
                std::vector<double>* x2_out, bool* finite) {
  using MatN = Eigen::Matrix<double, N, N>;
  using MatN3 = Eigen::Matrix<double, N, 3>;
  using VecN = Eigen::Matrix<double, N, 1>;
  const bool periodic = m.has(Effect::kPeriodicPosition);
  const bool backlash = m.has(Effect::kBacklash);
  const bool direction = m.has(Effect::kDirectionStiffness);
  const bool friction = m.has(Effect::kCoulombFriction);
  const bool positional = m.compliance_slope_per_m != 0.0;
  const bool nonlinear = periodic || backlash || direction || friction || positional;
  const double scale = m.has(Effect::kScaleError) ? m.scale : 1.0;
  const double k2 = m.k2_n_m;
  const double period_m = std::max(m.period_mm, 1e-3) * 1e-3;
  const double ps = m.periodic_sin_um * 1e-6, pc = m.periodic_cos_um * 1e-6;
  const double half_w = 0.5 * std::max(m.backlash_width_um, 0.0) * 1e-6;
  const double r = std::max(m.stiffness_ratio, 1e-3);
  const double k_pos = k2 * 2.0 * r / (1.0 + r), k_neg = k2 * 2.0 / (1.0 + r);
  const double fc = std::max(m.friction_force_n, 0.0);
  const double bristle_m =
      std::max(m.presliding_um, 0.1) * 1e-6;  // Dahl: deflection at full friction

  // Discretisation: u ramps linearly over each (sub)step (first-order hold, exact for the linear
  // part), the effect forces are held (zero-order hold). Augmented exponential
  //   exp([[A h, B h, 0], [0, 0, e_u], [0, 0, 0]]) = [[Ad, G0, G1], ...]
  // gives x+ = Ad x + G0 [u_a, F1, F2] + G1 (u_b - u_a).
  // Substeps resolve the force switches of backlash, direction-dependent stiffness and friction;
  // the runout force varies smoothly with position (a few Hz at print speeds), so held over a
  // whole sample it is as exact, and a runout alone is simulated at one step per sample.
  const bool switching = backlash || direction || friction;
  const int substeps = switching ? kSubsteps : 1;
  const double h = period_s / substeps;
  struct Disc {
    MatN Ad;
    MatN3 G0;
    VecN G1;
    VecN g_belt;  // G0's carriage column less its rotor column: a belt force between the two
  };
  const auto discretise = [&](const Mat6& A_belt, double hh, Disc* d) {
    Eigen::Matrix<double, N + 4, N + 4> M = Eigen::Matrix<double, N + 4, N + 4>::Zero();
    M.template topLeftCorner<N, N>() = A_belt.template topLeftCorner<N, N>() * hh;
    M.template block<N, 3>(0, N) = B.template topRows<N>() * hh;
    M(N, N + 3) = 1.0;
    const Eigen::Matrix<double, N + 4, N + 4> E = M.exp();
    d->Ad = E.template topLeftCorner<N, N>();
    d->G0 = E.template block<N, 3>(0, N);
    d->G1 = E.template block<N, 1>(0, N + 3);
    d->g_belt = d->G0.col(2) - d->G0.col(1);
    return d->Ad.allFinite() && d->G0.allFinite() && d->G1.allFinite();
  };
  // The belt's regimes: pulling + (s beyond the dead band, stiffness k_pos), pulling - (k_neg),
  // and slack inside the dead band (no belt force). Each is linear, so each substep is exact in
  // the regime it starts in (its stiffness in the matrices, the dead band's offset a held force)
  // and the force is continuous where the regimes meet. Held as a force instead, the difference
  // to the nominal k2 is a stiff explicit term: with 5 substeps, a calibrated belt of 650 kN/m
  // with a direction ratio of 0.67 beside 1.5 N of friction was 49 um off the path where the
  // converged simulation is 3.4 um off (tests/calibration/feedforward_inverts_ident_test.cpp).
  const bool regimes = backlash || direction;
  // Regime 0: the nominal k2 (no switching belt); 1: pulling +; 2: pulling -; 3: slack. A substep
  // that ends in another regime than it began in is simulated again in kCrossingSplit parts (the
  // matrices of h / kCrossingSplit), each in the regime it begins in: the crossing is then placed
  // within h / kCrossingSplit, and the substeps elsewhere stay whole.
  Disc coarse[4], fine[4], whole[4];
  const double k_regime[4] = {k2, direction ? k_pos : k2, direction ? k_neg : k2, 0.0};
  const auto with_belt = [&](double k_belt, double hh, Disc* d) {
    // A with the belt k2 (x1 - x2) replaced by k_belt (x1 - x2).
    Mat6 Ak = A;
    const double dk = k_belt - k2;
    Ak(1, 0) -= dk / m.m1_kg;
    Ak(1, 2) += dk / m.m1_kg;
    Ak(3, 0) += dk / m.m2_kg;
    Ak(3, 2) -= dk / m.m2_kg;
    return discretise(Ak, hh, d);
  };
  bool ok = discretise(A, h, &coarse[0]);
  if (regimes) {
    for (int rg = 1; rg <= (backlash ? 3 : 2); ++rg) {
      ok = ok && with_belt(k_regime[rg], h, &coarse[rg]) &&
           with_belt(k_regime[rg], h / kCrossingSplit, &fine[rg]) &&
           (friction || with_belt(k_regime[rg], period_s, &whole[rg]));
    }
  }
  const Disc& nominal = coarse[0];
  const MatN& Ad = nominal.Ad;
  const MatN3& G0 = nominal.G0;
  const VecN& G1 = nominal.G1;
  const size_t n = u_mm.size();
  std::vector<double>& x2 = *x2_out;
  x2.assign(n, 0.0);
  if (!ok) {
    *finite = false;
    return;
  }
  // The linear-only case: the input enters through column 0 of G0 only.
  const VecN g0u = G0.col(0);
  const VecN g1 = G1;

  // Work in metres relative to the first command: the runout phase is then relative to the
  // trace's start, which the fitted sin/cos pair absorbs.
  const double u0 = u_mm[0];
  VecN q = VecN::Zero();
  // At rest at the start: with a runout the belt leaves the pulley at x1 + b (x1 = 0), so the
  // carriage (and the extra mass) rest at b; the output is counted from that rest position (the
  // reading an incremental encoder is zeroed at).
  const double rest_m = periodic ? pc : 0.0;
  const double out_offset_m = -rest_m;
  q[2] = rest_m;
  if constexpr (N == 6) q[4] = rest_m;
  double z = 0.0;  // friction bristle
  double u_prev = 0.0;
  const double two_pi_over_p = 2.0 * kPi / period_m;
  // The belt's regime at stretch s (see k_regime).
  const auto regime_of = [&](double s) {
    if (!regimes) return 0;
    if (backlash && std::abs(s) <= half_w) return 3;
    return s > 0.0 ? 1 : 2;
  };
  // One step of length hh in regime rg from state (qs, zs): u ramps from u_a by du_step; the forces
  // beyond the regime's linear belt (the dead band's offset, the runout's share, the slope's
  // factor) and the friction held over it.
  const auto advance = [&](VecN& qs, double& zs, const Disc& d, int rg, double run, double hh,
                           double u_a, double du_step) {
    const double x1 = qs[0], xc = qs[2], vc = qs[3];
    const double s = x1 - xc + run;
    const double k_r = k_regime[rg];
    const double stretch = rg == 3 ? 0.0 : (rg == 1 ? s - half_w : (rg == 2 ? s + half_w : s));
    double kb = k_r;
    if (positional)
      kb *= model::belt_stiffness_factor(m.compliance_slope_per_m, m.stiffness_reference_mm,
                                         (xc - rest_m) * 1e3 + u0);
    const double df = kb * stretch - k_r * (x1 - xc);
    double f_fric = 0.0;
    if (friction) {
      // Dahl: dz/dt = v (1 - sgn(v) z / z_max), solved exactly over the step for fixed v.
      f_fric = -fc * zs / bristle_m;
      const double av = std::abs(vc);
      if (av > 0.0) {
        const double zss = vc > 0.0 ? bristle_m : -bristle_m;
        zs = zss + (zs - zss) * std::exp(-av * hh / bristle_m);
      }
    }
    qs = d.Ad * qs + d.G0.col(0) * u_a + d.g_belt * df + d.G0.col(2) * f_fric + d.G1 * du_step;
  };
  for (size_t k = 0; k < n; ++k) {
    const double u_k = scale * (u_mm[k] - u0) * 1e-3;
    if (k > 0) {
      const double du = (u_k - u_prev) / substeps;
      if (!nonlinear) {
        q = Ad * q + g0u * u_prev + g1 * du;
      } else {
        // Runout: exact sin/cos at the sample's first substep, then near that phase.
        double s_ref = 0.0, c_ref = 1.0, x1_ref = 0.0;
        if (periodic) {
          x1_ref = q[0];
          s_ref = std::sin(two_pi_over_p * x1_ref);
          c_ref = std::cos(two_pi_over_p * x1_ref);
        }
        // Far from the belt's next regime at its current rate (and without friction, whose
        // bristle follows the speed), the sample is one exact step of its regime; it is taken in
        // substeps only when it would end in another regime.
        if (regimes && !friction) {
          const double run = periodic ? ps * s_ref + pc * c_ref : 0.0;
          const double s0 = q[0] - q[2] + run;
          const int r0 = regime_of(s0);
          const double to_next = r0 == 3 ? half_w - std::abs(s0) : std::abs(s0) - half_w;
          if (to_next > 2.0 * std::abs(q[1] - q[3]) * period_s) {
            const VecN q_start = q;
            advance(q, z, whole[r0], r0, run, period_s, u_prev, u_k - u_prev);
            if (regime_of(q[0] - q[2] + run) == r0) {
              u_prev = u_k;
              x2[k] = (q[2] + out_offset_m) * 1e3 + u0;
              continue;
            }
            q = q_start;
          }
        }
        for (int j = 0; j < substeps; ++j) {
          // The belt's stretch at the substep's start, runout included.
          double run = 0.0;
          if (periodic) {
            double sn = s_ref, cs = c_ref;
            if (j > 0) sincos_near(s_ref, c_ref, two_pi_over_p * (q[0] - x1_ref), &sn, &cs);
            run = ps * sn + pc * cs;
          }
          const double u_a = u_prev + du * j;
          if (!regimes) {
            advance(q, z, coarse[0], 0, run, h, u_a, du);
            continue;
          }
          const int r0 = regime_of(q[0] - q[2] + run);
          const VecN q_start = q;
          const double z_start = z;
          advance(q, z, coarse[r0], r0, run, h, u_a, du);
          if (regime_of(q[0] - q[2] + run) == r0) continue;
          q = q_start;  // a crossing: again in parts, each in the regime it begins in
          z = z_start;
          for (int i = 0; i < kCrossingSplit; ++i) {
            const int rg = regime_of(q[0] - q[2] + run);
            advance(q, z, fine[rg], rg, run, h / kCrossingSplit, u_a + du * i / kCrossingSplit,
                    du / kCrossingSplit);
          }
        }
      }
    }
    u_prev = u_k;
    x2[k] = (q[2] + out_offset_m) * 1e3 + u0;
  }
}

}  // namespace

std::vector<double> field_command(const AxisModel& m, const std::vector<double>& u_mm,
                                  double period_s) {
  if (!(m.field_lag_ms > 0.0) || u_mm.empty()) return u_mm;
  // (1 + T s) / (1 + tau s): the inverse of the LPV feedforward's (model/lead_lag.hpp).
  const model::TustinLeadLag f =
      model::tustin_lead_lag(m.c1_n_s_m / m.k1_n_m, m.field_lag_ms * 1e-3, period_s);
  std::vector<double> out(u_mm.size());
  double x_prev = u_mm[0], y_prev = u_mm[0];
  for (size_t k = 0; k < u_mm.size(); ++k) {
    const double y = f.b0 * u_mm[k] + f.b1 * x_prev - f.a1 * y_prev;
    x_prev = u_mm[k];
    y_prev = y;
    out[k] = y;
  }
  return out;
}

model::StateSpace axis_state_space(const AxisModel& m) {
  Mat6 A;
  Mat63 B;
  linear_part(m, &A, &B);
  const int n = m.has(Effect::kExtraResonance) ? 6 : 4;
  model::StateSpace sys;
  sys.A = A.topLeftCorner(n, n);
  sys.B = B.block(0, 0, n, 1);
  sys.C = Eigen::MatrixXd::Zero(1, n);
  sys.C(0, 2) = 1.0;
  sys.D = Eigen::MatrixXd::Zero(1, 1);
  return sys;
}

Status simulate_axis(const AxisModel& m, const std::vector<double>& u_mm, double period_s, std::vector<double>* y_mm) {
  const double vals[] = {m.m1_kg,
                         m.m2_kg,
                         m.k1_n_m,
                         m.k2_n_m,
                         m.c1_n_s_m,
                         m.c2_n_s_m,
                         m.scale,
                         m.delay_ms,
                         m.period_mm,
                         m.extra_freq_hz,
                         m.extra_damping,
                         m.extra_mass_kg,
                         m.stiffness_ratio,
                         m.friction_force_n,
                         m.presliding_um,
                         m.backlash_width_um,
                         m.periodic_sin_um,
                         m.periodic_cos_um,
                         m.compliance_slope_per_m,
                         m.stiffness_reference_mm,
                         m.field_lag_ms};
  for (double v : vals)
    if (!std::isfinite(v)) return Error{"axis model has a non-finite parameter", {}};
  if (!(period_s > 0.0)) return Error{"sample period must be > 0", {}};
  if (!(m.m1_kg > 0.0 && m.m2_kg > 0.0)) return Error{"masses must be > 0", {}};
  const size_t n = u_mm.size();
  y_mm->assign(n, 0.0);
  if (n == 0) return Status::Ok();
  Mat6 A;
  Mat63 B;
  linear_part(m, &A, &B);
  std::vector<double> x2;
  bool finite = true;
  const std::vector<double> u_lagged =
      m.field_lag_ms > 0.0 ? field_command(m, u_mm, period_s) : std::vector<double>{};
  const std::vector<double>& u_in = m.field_lag_ms > 0.0 ? u_lagged : u_mm;
  if (m.has(Effect::kExtraResonance))
    run_states<6>(m, A, B, u_in, period_s, &x2, &finite);
  else
    run_states<4>(m, A, B, u_in, period_s, &x2, &finite);
  if (!finite) return Error{"axis model discretisation failed", {}};
  // time_delay: y(t) = x2(t - d), Catmull-Rom cubic interpolation (continuous slope in d, so the
  // fit does not stall at whole samples), held at the first sample before the start.
  if (m.has(Effect::kTimeDelay) && m.delay_ms > 0.0) {
    const double d = m.delay_ms * 1e-3 / period_s;
    const auto whole = static_cast<long>(std::floor(d));
    const double f = d - static_cast<double>(whole);
    const auto at = [&](long i) { return x2[static_cast<size_t>(std::clamp(i, 0L, static_cast<long>(n) - 1))]; };
    // Going back in time by f between p1 = x2[k - whole] and p2 = x2[k - whole - 1].
    const double w0 = 0.5 * (-f + 2.0 * f * f - f * f * f), w1 = 0.5 * (2.0 - 5.0 * f * f + 3.0 * f * f * f),
                 w2 = 0.5 * (f + 4.0 * f * f - 3.0 * f * f * f), w3 = 0.5 * (-f * f + f * f * f);
    for (size_t k = 0; k < n; ++k) {
      const long i = static_cast<long>(k) - whole;
      (*y_mm)[k] = w0 * at(i + 1) + w1 * at(i) + w2 * at(i - 1) + w3 * at(i - 2);
    }
  } else {
    *y_mm = std::move(x2);
  }
  if (!std::isfinite((*y_mm)[n - 1])) return Error{"axis model simulation diverged", {}};
  return Status::Ok();
}

}  // namespace feedloop::ident
