// Simulation of the identification's axis model (see axis_model.hpp).
#include "ident/axis_model.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>
#include <unsupported/Eigen/MatrixFunctions>

namespace feedloop::ident {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kSubsteps = 5;
constexpr double kBristle_m = 20e-6;  // Dahl bristle deflection at full sliding friction

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

Status simulate_axis(const AxisModel& m, const std::vector<double>& u_mm, double period_s, std::vector<double>* y_mm) {
  const double vals[] = {m.m1_kg, m.m2_kg, m.k1_n_m, m.k2_n_m, m.c1_n_s_m, m.c2_n_s_m, m.scale, m.delay_ms,
                         m.period_mm, m.extra_freq_hz, m.extra_damping, m.extra_mass_kg, m.stiffness_ratio,
                         m.friction_force_n, m.backlash_width_um, m.periodic_sin_um, m.periodic_cos_um};
  for (double v : vals)
    if (!std::isfinite(v)) return Error{"axis model has a non-finite parameter", {}};
  if (!(period_s > 0.0)) return Error{"sample period must be > 0", {}};
  if (!(m.m1_kg > 0.0 && m.m2_kg > 0.0)) return Error{"masses must be > 0", {}};
  const size_t n = u_mm.size();
  y_mm->assign(n, 0.0);
  if (n == 0) return Status::Ok();

  // Continuous linear part: q = [x1, v1, x2, v2, x3, v3], inputs [u, F_rotor, F_carriage] (Eq. 13).
  const bool extra = m.has(Effect::kExtraResonance);
  Mat6 A = Mat6::Zero();
  Mat63 B = Mat63::Zero();
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
  // Nominal belt k2 (x1 - x2) in the linear part; the effects add a correction force.
  A(1, 0) -= k2 / m.m1_kg;
  A(1, 2) += k2 / m.m1_kg;
  A(3, 0) += k2 / m.m2_kg;
  A(3, 2) -= k2 / m.m2_kg;
  if (extra) {
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
    A(4, 4) = -1.0;  // unused states decay (keeps the exponential well conditioned)
    A(5, 5) = -1.0;
  }
  // Discretisation: u ramps linearly over each (sub)step (first-order hold, exact for the linear
  // part), the effect forces are held (zero-order hold). Augmented exponential
  //   exp([[A h, B h, 0], [0, 0, e_u], [0, 0, 0]]) = [[Ad, G0, G1], ...]
  // gives x+ = Ad x + G0 [u_a, F1, F2] + G1 (u_b - u_a).
  struct Disc {
    Mat6 Ad;
    Mat63 G0;
    Vec6 G1;
  };
  auto discretise = [&](double h) {
    Eigen::Matrix<double, 10, 10> M = Eigen::Matrix<double, 10, 10>::Zero();
    M.topLeftCorner<6, 6>() = A * h;
    M.block<6, 3>(0, 6) = B * h;
    M(6, 9) = 1.0;
    const Eigen::Matrix<double, 10, 10> E = M.exp();
    return Disc{E.topLeftCorner<6, 6>(), E.block<6, 3>(0, 6), E.block<6, 1>(0, 9)};
  };
  const bool periodic = m.has(Effect::kPeriodicPosition);
  const bool backlash = m.has(Effect::kBacklash);
  const bool direction = m.has(Effect::kDirectionStiffness);
  const bool friction = m.has(Effect::kCoulombFriction);
  const bool nonlinear = periodic || backlash || direction || friction;
  const double scale = m.has(Effect::kScaleError) ? m.scale : 1.0;
  const double period_m = std::max(m.period_mm, 1e-3) * 1e-3;
  const double ps = m.periodic_sin_um * 1e-6, pc = m.periodic_cos_um * 1e-6;
  const double half_w = 0.5 * std::max(m.backlash_width_um, 0.0) * 1e-6;
  const double r = std::max(m.stiffness_ratio, 1e-3);
  const double k_pos = k2 * 2.0 * r / (1.0 + r), k_neg = k2 * 2.0 / (1.0 + r);
  const double fc = std::max(m.friction_force_n, 0.0);

  // Work in metres relative to the first command: the runout phase is then relative to the
  // trace's start, which the fitted sin/cos pair absorbs.
  const int substeps = nonlinear ? kSubsteps : 1;
  const double h = period_s / substeps;
  const Disc D = discretise(h);
  if (!D.Ad.allFinite() || !D.G0.allFinite() || !D.G1.allFinite())
    return Error{"axis model discretisation failed", {}};
  const double u0 = u_mm[0];
  Vec6 q = Vec6::Zero();
  double z = 0.0;  // friction bristle
  std::vector<double> x2(n, 0.0);
  double u_prev = 0.0;
  for (size_t k = 0; k < n; ++k) {
    const double u_k = scale * (u_mm[k] - u0) * 1e-3;
    if (k > 0) {
      const double du = (u_k - u_prev) / substeps;
      for (int j = 0; j < substeps; ++j) {
        Eigen::Vector3d in(u_prev + du * j, 0.0, 0.0);
        if (nonlinear) {
          const double x1 = q[0], xc = q[2], vc = q[3];
          double s = x1 - xc;
          if (periodic) s += ps * std::sin(2.0 * kPi * x1 / period_m) + pc * std::cos(2.0 * kPi * x1 / period_m);
          if (backlash) s = s > half_w ? s - half_w : (s < -half_w ? s + half_w : 0.0);
          const double kb = direction ? (s > 0.0 ? k_pos : k_neg) : k2;
          const double df = kb * s - k2 * (x1 - xc);  // correction to the linear belt force
          double f_fric = 0.0;
          if (friction) {
            // Dahl: dz/dt = v (1 - sgn(v) z / z_max), solved exactly over the substep for fixed v.
            f_fric = -fc * z / kBristle_m;
            const double av = std::abs(vc);
            if (av > 0.0) {
              const double zss = vc > 0.0 ? kBristle_m : -kBristle_m;
              z = zss + (z - zss) * std::exp(-av * h / kBristle_m);
            }
          }
          in[1] = -df;
          in[2] = df + f_fric;
        }
        q = D.Ad * q + D.G0 * in + D.G1 * du;
      }
    }
    u_prev = u_k;
    x2[k] = q[2] * 1e3 + u0;
  }
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
