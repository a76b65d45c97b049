// The output-maneuvering controller of output-maneuvering-cartesian Sect. III-C (Lyapunov
// backstepping after Skjetne et al.), for the plant M x_2' + D x_2 = k_1 w (printer_model.hpp).
//
//   z_1 = x_1 - y_d(theta)                                                     (Eq. 26/59)
//   alpha_1 = A_1 z_1 + dy_d/dtheta v_s,  A_1 = -K_p                            (Eq. 33/61)
//   z_2 = x_2 - alpha_1                                                         (Eq. 27/60)
//   dalpha_1/dtheta = K_p dy_d/dtheta + dy_d/dtheta dv_s/dtheta                 (Eq. 62)
//   w = M/k_1 (A_2 z_2 - P_2^-1 P_1 z_1 + M^-1 D x_2 + A_1 x_2
//              + dalpha_1/dtheta v_s),  A_2 = -K_d                              (Eq. 45)
//   theta' = v_s(theta) - omega_s                                               (Eq. 56)
//   omega_s' = -lambda (omega_s + mu z^T P b),  z^T P b = tau_1 + tau_2
//            = z_1^T P_1 dy_d/dtheta + z_2^T P_2 dalpha_1/dtheta                 (Eq. 48-52)
//   V = 1/2 z_1^T P_1 z_1 + 1/2 z_2^T P_2 z_2 + omega_s^2 / (2 lambda mu)       (Eq. 30, 37, 51)
// with P_i the solution of P_i A_i + A_i^T P_i = -Q_i: for diagonal gains P_i = Q_i / (2 K_i).
// Along a segment V' = -1/2 z^T Q z - omega_s^2 / mu <= 0 (Eq. 55). At a waypoint dy_d/dtheta
// jumps, so alpha_1, z_2 and V jump there.
// Two of the paper's summary equations disagree with its derivation; this follows the derivation:
// Eq. 58 has +P_2^-1 P_1 z_1 where Eq. 45 (which cancels the z_1^T P_1 z_2 cross term) has a minus,
// and Eq. 57 has 2 lambda mu where Eq. 52 (which makes Eq. 53-55 hold) has lambda mu.
// The z voltage adds the Eq. 14 gravity offset. evaluate() allocates nothing.
#pragma once

#include <cstddef>

#include "maneuver/path.hpp"
#include "maneuver/printer_model.hpp"
#include "maneuver/speed_assignment.hpp"

namespace feedloop::maneuver {

// Table II (diagonal matrices as scalars times I).
struct ManeuverGains {
  double k_p = 500.0;    // K_p = -A_1, 1/s
  double k_d = 1667.0;   // K_d = -A_2, 1/s
  double q1 = 1.0;       // Q_1 = q1 I
  double q2 = 1.0;       // Q_2 = q2 I
  double lambda = 30.0;  // filter cut-off of the gradient update, rad/s
  double mu = 1000.0;    // mu_1: gradient update gain
  // true: the summary equations as printed, Eq. 58's +P_2^-1 P_1 z_1 and Eq. 57's 2 lambda mu,
  // instead of the derivation's Eq. 45 and Eq. 52 (only to measure what the misprint would cost).
  bool as_printed = false;
};

struct ManeuverState {
  double theta = 0.0;    // path variable
  double omega_s = 0.0;  // omega_s = v_s - theta' (Eq. 28)
};

struct ManeuverOutput {
  Vec3 w_v = Vec3::Zero();  // motor voltages [V_x, V_y, V'_z] (z includes the Eq. 14 offset)
  double dtheta = 0.0;      // theta' (Eq. 56)
  double domega_s = 0.0;    // omega_s' (Eq. 52)
  Vec3 z1_m = Vec3::Zero();
  Vec3 z2_m_s = Vec3::Zero();
  double lyapunov = 0.0;    // V of Eq. 51
  SpeedValue speed;         // v_s, dv_s/dtheta at theta
};

class ManeuverController {
 public:
  ManeuverController(const CartesianDcPlant& plant, const ManeuverGains& gains);

  const ManeuverGains& gains() const { return g_; }
  double p1() const { return p1_; }  // P_1 = p1 I
  double p2() const { return p2_; }  // P_2 = p2 I

  // The control law at plant state x and controller state c, with theta on segment n.
  ManeuverOutput evaluate(const PiecewiseLinearPath& path, const SpeedAssignment& speed,
                          const PlantState& x, const ManeuverState& c, size_t n) const;
  // The same law from the local path data: y_d(theta), dy_d/dtheta of the segment, and v_s,
  // dv_s/dtheta at theta (what a streaming path window supplies). With v_s = 0 and dy_d/dtheta = 0
  // it holds the plant at y_d. Allocation-free.
  ManeuverOutput evaluate_at(const Vec3& yd, const Vec3& dyd, const SpeedValue& speed, const PlantState& x,
                             const ManeuverState& c) const;

 private:
  PrinterMatrices mat_;
  double gravity_offset_v_;
  ManeuverGains g_;
  double p1_, p2_;
};

}  // namespace feedloop::maneuver
