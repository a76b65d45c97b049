// Speed assignments v_s(theta) for output maneuvering (output-maneuvering-cartesian Sect. III-D).
// Each gives the path speed as m_s times a dimensionless factor f in [0, 1]; in the path variable,
//   v_s = m_s f / ||dy_d/dtheta||,   dv_s/dtheta = m_s (df/dtheta) / ||dy_d/dtheta||.
//
//   constant          f = 1                                                              (Eq. 63)
//   every_transition  Eq. 67 with k_n = 1 at every waypoint: the sigmoid slow-down at the start
//                     and end of every segment of Skjetne et al. as the paper uses it
//   sharp_corner      Eq. 67 with k_n of Eq. 64-66 (k_0 = k_N = 1): slow down only at corners
//                     sharper than alpha_a, fully above alpha_b. With u = (theta - theta_{n-1}) /
//                     (theta_n - theta_{n-1}) the fraction of segment n travelled,
//                       f = k_{n-1} h(u) + (1 - k_{n-1}) h(1/2)          on u < 1/2,
//                       f = k_n h(1 - u) + (1 - k_n) h(1/2)              on u >= 1/2,
//                     h of Eq. 68 (planner::sharp_corner_h). With the unit parameterisation u is
//                     theta - theta_{n-1} and this is the paper's Eq. 67 exactly.
//   sharp_corner_arc  ours, from the paper's own caveat (Sect. V-A): the same corner weights k_j,
//                     but the sigmoid runs over distance d_j = |s - s_j| (metres) to each corner j,
//                     not over the fraction of the segment, and every corner within reach counts:
//                       f(s) = min_j [ k_j hc(d_j) + 1 - k_j ],   hc(d) = min(1, h_L(d) / h_L(W))
//                     with h_L(d) = atan((d - a1_m)/a2_m)/pi + 1/2 (Eq. 68 in metres) and W the
//                     reach. The slow-down then has the same length before every corner, a short
//                     segment does not shorten it (no fast transients), a sharp corner just past a
//                     short segment is still seen, and f is continuous (hc reaches 1 at W).
// Note: Eq. 69 misses the 1/pi of h'(theta) = a_2 / (pi (a_2^2 + (theta - a_1)^2)); the
// derivative here is that of Eq. 67/68 as written.
#pragma once

#include <vector>

#include "core/result.hpp"
#include "maneuver/path.hpp"
#include "planner/config.hpp"

namespace feedloop::maneuver {

enum class SpeedProfile { constant, every_transition, sharp_corner, sharp_corner_arc };
const char* to_string(SpeedProfile p);

struct SpeedParams {
  double m_s_m_s = 0.1;                // m_s: the target path speed (Fig. 7: 0.1 m/s)
  planner::SharpCornerParams sharp{};  // alpha_a 5 deg, alpha_b 20 deg, a_1 0.05, a_2 0.005 (Table II)
  // sharp_corner_arc only: the Eq. 68 sigmoid in metres and its reach W.
  // a1/a2 = 12 gives a corner speed h_L(0) = 0.026 m_s (the paper's a_1/a_2 = 10: 0.032 m_s);
  // the short zone suits this model (exact feedforward, no voltage limit): on a real machine the
  // acceleration limits set it. bench/maneuver/README.md shows how they were chosen.
  double a1_m = 0.06e-3;
  double a2_m = 0.005e-3;
  double reach_m = 2.0e-3;
};

// Eq. 67 on a segment with corner weights k_prev (at its start) and k_next (at its end), u the
// fraction of the segment travelled; df_du its derivative. Shared by SpeedAssignment and the
// streaming path window (stream.hpp).
double paper_speed_factor(double u, double k_prev, double k_next, const planner::SharpCornerParams& p,
                          double& df_du);
// One corner's term of the arc-length variant: k hc(d) + 1 - k at distance d (m) from the corner,
// hc(d) = h_L(d) / h_reach; dg_dd its derivative in d.
double arc_corner_factor(double d_m, double k, const planner::SharpCornerParams& sigmoid_m, double h_reach,
                         double& dg_dd);

struct SpeedValue {
  double v_s = 0.0;          // v_s(theta), path-variable units per second
  double dv_s_dtheta = 0.0;  // dv_s/dtheta
  double factor = 0.0;       // f: path speed / m_s
};

class SpeedAssignment {
 public:
  // Errors: m_s not positive, alpha_b <= alpha_a, a_2 (or a2_m) not positive, reach below a1_m.
  static Result<SpeedAssignment> create(const PiecewiseLinearPath& path, SpeedProfile profile,
                                        const SpeedParams& params);

  SpeedProfile profile() const { return profile_; }
  const SpeedParams& params() const { return params_; }
  double k(size_t n) const { return k_[n]; }  // k_n of Eq. 66 (all 1 for every_transition)

  // v_s and dv_s/dtheta at theta on segment n of `path` (the path it was created for).
  // Real-time safe: no allocation.
  SpeedValue at(const PiecewiseLinearPath& path, double theta, size_t n) const;

 private:
  double factor_paper(double u, size_t n, double& df_du) const;
  double factor_arc(const PiecewiseLinearPath& path, double s_m, size_t n, double& df_ds) const;

  SpeedProfile profile_ = SpeedProfile::constant;
  SpeedParams params_;
  planner::SharpCornerParams arc_sigmoid_;  // a1_m, a2_m in the a1, a2 slots
  double h_reach_ = 1.0;                    // h_L(W)
  std::vector<double> k_;                   // k_0..k_N
};

}  // namespace feedloop::maneuver
