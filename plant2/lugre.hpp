// LuGre friction (Canudas de Wit, Olsson, Astrom, Lischinsky 1995) for the carriage's bearings:
// one bristle state z (m),
//   dz/dt = v - sigma0 |v| z / g(v),   g(v) = F_c + (F_s - F_c) exp(-(v / v_s)^2)   (Stribeck)
//   F     = sigma0 z + sigma1 dz/dt + sigma2 v.
// At constant speed z settles at g(v) sgn(v) / sigma0, so F = g(v) sgn(v) + sigma2 v. Below the
// breakaway force F_s the bristles deflect elastically (pre-sliding, a few um) and the carriage
// sticks.
//
// z is advanced with the exact solution for v held over the step (dz/dt is linear in z then):
// stable for any step, whatever sigma0 |v| / g is.
#pragma once

#include <cmath>

namespace feedloop::plant2 {

struct LuGreParams {
  double coulomb_n = 0.0;      // F_c
  double static_n = 0.0;       // F_s >= F_c
  double stribeck_m_s = 1e-3;  // v_s
  double sigma0_n_m = 1e5;     // bristle stiffness
  double sigma1_n_s_m = 0.0;   // bristle damping
  double sigma2_n_s_m = 0.0;   // viscous
};

class LuGre {
 public:
  LuGre() = default;
  explicit LuGre(const LuGreParams& p) : p_(p) {}

  // The Stribeck curve g(v) (N, > 0 unless there is no friction).
  double stribeck_n(double v_m_s) const {
    const double s = v_m_s / p_.stribeck_m_s;
    return p_.coulomb_n + (p_.static_n - p_.coulomb_n) * std::exp(-s * s);
  }

  // dz/dt at speed v for the current z.
  double z_rate(double v_m_s) const {
    const double g = stribeck_n(v_m_s);
    if (g <= 0.0) return 0.0;
    return v_m_s - p_.sigma0_n_m * std::fabs(v_m_s) * z_ / g;
  }

  // The friction force at speed v (opposes motion when subtracted from the applied force).
  double force_n(double v_m_s) const {
    return p_.sigma0_n_m * z_ + p_.sigma1_n_s_m * z_rate(v_m_s) + p_.sigma2_n_s_m * v_m_s;
  }

  // Advances z over dt with v held: z -> z_ss + (z - z_ss) exp(-a dt), a = sigma0 |v| / g.
  void advance(double v_m_s, double dt_s) {
    const double g = stribeck_n(v_m_s);
    if (g <= 0.0) {
      z_ = 0.0;
      return;
    }
    const double a = p_.sigma0_n_m * std::fabs(v_m_s) / g;
    if (a * dt_s < 1e-9) {
      z_ += v_m_s * dt_s;  // |v| ~ 0: the bristles follow the (tiny) motion elastically
      return;
    }
    const double z_ss = v_m_s / a;
    z_ = z_ss + (z_ - z_ss) * std::exp(-a * dt_s);
  }

  // One integration step: the force at speed v for the current z (returned), then z advanced over
  // dt with v held, g(v) evaluated once for both.
  double step(double v_m_s, double dt_s) {
    if (v_m_s == 0.0) return p_.sigma0_n_m * z_;  // at rest: dz/dt = 0
    const double g = stribeck_n(v_m_s);
    if (g <= 0.0) {
      z_ = 0.0;
      return p_.sigma2_n_s_m * v_m_s;
    }
    const double a = p_.sigma0_n_m * std::fabs(v_m_s) / g;
    const double rate = v_m_s - a * z_;
    const double f = p_.sigma0_n_m * z_ + p_.sigma1_n_s_m * rate + p_.sigma2_n_s_m * v_m_s;
    if (a * dt_s < 1e-9) {
      z_ += v_m_s * dt_s;
    } else {
      const double z_ss = v_m_s / a;
      z_ = z_ss + (z_ - z_ss) * std::exp(-a * dt_s);
    }
    return f;
  }

  double z_m() const { return z_; }
  void set_z_m(double z) { z_ = z; }
  const LuGreParams& params() const { return p_; }

 private:
  LuGreParams p_;
  double z_ = 0.0;
};

}  // namespace feedloop::plant2
