// Speed assignments of Eq. 63, Eq. 66-68 and the arc-length variant (see speed_assignment.hpp).
#include "maneuver/speed_assignment.hpp"

#include <algorithm>  // std::min
#include <cmath>      // std::atan

#include "planner/junction.hpp"

namespace feedloop::maneuver {

namespace {
constexpr double kPi = 3.14159265358979323846;

// h'(x) for h(x) = atan((x - a1)/a2)/pi + 1/2 (Eq. 68).
double sigmoid_slope(double x, double a1, double a2) {
  const double d = x - a1;
  return a2 / (kPi * (a2 * a2 + d * d));
}
}  // namespace

double paper_speed_factor(double u, double k_prev, double k_next, const planner::SharpCornerParams& p,
                          double& df_du) {
  const double h_half = planner::sharp_corner_h(0.5, p);
  if (u < 0.5) {  // Eq. 67, first half: the corner behind
    df_du = k_prev * sigmoid_slope(u, p.a1, p.a2);
    return k_prev * planner::sharp_corner_h(u, p) + (1.0 - k_prev) * h_half;
  }
  df_du = -k_next * sigmoid_slope(1.0 - u, p.a1, p.a2);  // Eq. 67, second half: the corner ahead
  return k_next * planner::sharp_corner_h(1.0 - u, p) + (1.0 - k_next) * h_half;
}

double arc_corner_factor(double d_m, double k, const planner::SharpCornerParams& sigmoid_m, double h_reach,
                         double& dg_dd) {
  dg_dd = k * sigmoid_slope(d_m, sigmoid_m.a1, sigmoid_m.a2) / h_reach;
  return k * planner::sharp_corner_h(d_m, sigmoid_m) / h_reach + 1.0 - k;
}

const char* to_string(SpeedProfile p) {
  switch (p) {
    case SpeedProfile::constant: return "constant";
    case SpeedProfile::every_transition: return "every_transition";
    case SpeedProfile::sharp_corner: return "sharp_corner";
    case SpeedProfile::sharp_corner_arc: return "sharp_corner_arc";
  }
  return "?";
}

Result<SpeedAssignment> SpeedAssignment::create(const PiecewiseLinearPath& path, SpeedProfile profile,
                                                const SpeedParams& params) {
  if (!(params.m_s_m_s > 0.0)) return Error{"speed assignment: m_s must be positive", {}};
  if (!(params.sharp.alpha_b_deg > params.sharp.alpha_a_deg))
    return Error{"speed assignment: alpha_b must exceed alpha_a", {}};
  if (!(params.sharp.a2 > 0.0)) return Error{"speed assignment: a_2 must be positive", {}};
  if (profile == SpeedProfile::sharp_corner_arc &&
      !(params.a2_m > 0.0 && params.a1_m >= 0.0 && params.reach_m > params.a1_m + params.a2_m))
    return Error{"speed assignment: arc variant needs a2_m > 0, a1_m >= 0, reach_m > a1_m + a2_m", {}};

  SpeedAssignment a;
  a.profile_ = profile;
  a.params_ = params;
  a.arc_sigmoid_ = params.sharp;
  a.arc_sigmoid_.a1 = params.a1_m;
  a.arc_sigmoid_.a2 = params.a2_m;
  a.h_reach_ = planner::sharp_corner_h(params.reach_m, a.arc_sigmoid_);
  const size_t n_seg = path.segments();
  a.k_.assign(n_seg + 1, 1.0);  // k_0 = k_N = 1: start and end near rest
  for (size_t n = 1; n < n_seg; ++n) {
    if (profile == SpeedProfile::constant) a.k_[n] = 0.0;
    else if (profile == SpeedProfile::every_transition) a.k_[n] = 1.0;
    else a.k_[n] = planner::sharp_corner_k(path.corner_angle_deg(n), params.sharp);  // Eq. 64-66
  }
  return a;
}

double SpeedAssignment::factor_paper(double u, size_t n, double& df_du) const {
  return paper_speed_factor(u, k_[n - 1], k_[n], params_.sharp, df_du);
}

double SpeedAssignment::factor_arc(const PiecewiseLinearPath& path, double s, size_t n,
                                   double& df_ds) const {
  double f = 1.0;
  df_ds = 0.0;
  const double reach = params_.reach_m;
  auto consider = [&](size_t j) {  // corner j at p_j
    const double d = std::abs(s - path.arc_length_at(j));
    if (d >= reach || k_[j] == 0.0) return;
    double dg_dd = 0.0;
    const double g = arc_corner_factor(d, k_[j], arc_sigmoid_, h_reach_, dg_dd);
    if (g < f) {
      f = g;
      const double sign = s >= path.arc_length_at(j) ? 1.0 : -1.0;
      df_ds = sign * dg_dd;
    }
  };
  // Corners behind (p_{n-1}, p_{n-2}, ...) and ahead (p_n, p_{n+1}, ...) while within reach.
  for (size_t j = n; j-- > 0;) {
    if (s - path.arc_length_at(j) >= reach) break;
    consider(j);
  }
  for (size_t j = n; j <= path.segments(); ++j) {
    if (path.arc_length_at(j) - s >= reach) break;
    consider(j);
  }
  return f;
}

SpeedValue SpeedAssignment::at(const PiecewiseLinearPath& path, double theta, size_t n) const {
  const double dtheta_seg = path.theta(n) - path.theta(n - 1);
  const double len = path.segment_length_m(n);
  const double speed_scale = params_.m_s_m_s * dtheta_seg / len;  // m_s / ||dy_d/dtheta||
  SpeedValue v;
  double df_dtheta = 0.0;
  switch (profile_) {
    case SpeedProfile::constant:
      v.factor = 1.0;  // Eq. 63
      break;
    case SpeedProfile::every_transition:
    case SpeedProfile::sharp_corner: {
      const double u = (theta - path.theta(n - 1)) / dtheta_seg;
      double df_du = 0.0;
      v.factor = factor_paper(u, n, df_du);
      df_dtheta = df_du / dtheta_seg;
      break;
    }
    case SpeedProfile::sharp_corner_arc: {
      double df_ds = 0.0;
      v.factor = factor_arc(path, path.arc_length(theta, n), n, df_ds);
      df_dtheta = df_ds * len / dtheta_seg;
      break;
    }
  }
  v.v_s = speed_scale * v.factor;
  v.dv_s_dtheta = speed_scale * df_dtheta;
  return v;
}

}  // namespace feedloop::maneuver
