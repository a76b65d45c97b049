// Model-based LPV feedforward for a Cartesian or CoreXY machine: per X and Y joint, the preview
// inverse (preview_design.hpp) of the thesis's two-mass stepper + belt model (closed-loop-gantry
// thesis, Eq. 13-16) whose belt stiffness depends on the carriage position AND on the direction
// of the belt stretch (Eq. 5-6, x0 = 0):
//   K2(x, s) = k_hat / (L - x s),   s = sgn(x1 - x2) = sgn(F),  K2(0, s) = k_hat / L.
// The stretch sign is the sign of the force the belt transmits to the carriage, which the plan
// predicts: F = m2 a + c2 v (planned acceleration and velocity from r_{k-1}, r_k, r_{k+1}).
// Designs are precomputed for both directions on a grid over the travel (2 x grid_points) and
// blended every period: linear in the reference position r_k, and with the smooth weight
//   w+ = 0.5 + 0.5 tanh(F / F0)
// in the direction (bilinear, 4 designs). direction_scheduled = false gives the earlier model:
// the direction average K2(x) = k_hat L / (L^2 - x^2), linear in r_k only.
// Coulomb friction (not in Eq. 13; the identified coulomb_friction effect): a Dahl model run on the
// planned carriage position, dz = dr (1 - sgn(dr) z / z_max), gives the friction force
// F_c z / z_max that the belt must add to m2 a + c2 v; the command moves by it through the
// chain's static compliance, 1 / k1 + 1 / K2(x, s) (motor and belt in series), and the force
// joins the planned belt force that picks the stretch direction.
// Runout (the identified periodic_position): the command moves by -runout(r) (gantry_lpv.hpp).
// Backlash (the identified backlash effect): a dead band of width w between pulley and belt; the
// command moves by (w / 2) tanh(F / F0) on the planned belt force F, so that the pulley is across
// the gap on the side that pulls before the force is needed.
// Scale (the identified scale_error): the carriage travels s mm per mm of steps, counted from
// where the steps and the encoder were last referenced to each other (rereference()), so the
// command is p + (u - p) / s with u the inverse's command for the carriage and p that point.
// Extra mode (the identified extra_resonance): a mass on a spring-damper on the carriage joins
// the model of every design (six states), so the inverse also commands what holds that mass on
// the path.
// Z and E pass through, delayed by P periods so every joint's command is for the same t_k.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "control/feedforward.hpp"
#include "control/feedforward/lpv_options.hpp"
#include "control/feedforward/scheduled_inverse.hpp"
#include "core/result.hpp"
#include "model/gantry_axis.hpp"
#include "model/lead_lag.hpp"

namespace feedloop::control {

struct GantryAxisLpvModel {
  model::GantryAxisParams params;     // Eq. 13; params.k2_n_m is replaced by K2(x) at each grid point
  double belt_unit_stiffness_n = 0;   // k_hat of Eq. 6; <= 0: constant k2 (no position dependence)
  double pulley_distance_mm = 300.0;  // L of Eq. 6
  // r = K2 pulling + / K2 pulling - beyond Eq. 6 (the identified direction_dependent_stiffness,
  // a ratio constant along the travel): the belt is 2 r / (1 + r) times Eq. 6's (or k2's)
  // stiffness pulling + and 2 / (1 + r) times pulling -, so the two directions' mean stays. 1:
  // none.
  double direction_ratio = 1.0;
  // The belt's compliance along the travel without Eq. 6's geometry (the calibrated belt):
  // K2(x) = k2 / (1 + s (x - reference)), s in 1/m (0: none); used when belt_unit_stiffness_n
  // <= 0, held within 0.2-5 k2 (as identification reads it, ident/axis_model.hpp).
  double compliance_slope_per_m = 0.0;
  double stiffness_reference_mm = 0.0;
  double min_mm = -100.0;             // travel covered by the grid (clamped to |x| <= 0.8 L)
  double max_mm = 100.0;
  int grid_points = 25;
  // Schedule on the stretch direction too (needs belt_unit_stiffness_n > 0 or a direction_ratio
  // other than 1). false: the
  // direction-averaged K2 (the F0 -> infinity limit, up to blending designs vs averaging K2).
  bool direction_scheduled = true;
  // F0 of the direction weight, N: the planned belt force at which the blend is 88 % one
  // direction (tanh(1) = 0.76). docs/feedforward.md has the measurement behind the default.
  double direction_force_n = 0.5;
  // Coulomb friction on the carriage, N (0: none), and the Dahl bristle deflection at which it
  // is fully developed (the simulator's and the identification's 20 um).
  double coulomb_friction_n = 0.0;
  double friction_bristle_mm = 0.02;
  // Backlash (not in Eq. 13; the identified backlash effect, the simulators' dead band between
  // the pulley and the belt), mm (0: none). The belt carries force only beyond half the width
  // either side, so the command leads by (w / 2) tanh(F / F0) with F the planned belt force
  // (friction included) and F0 = direction_force_n: across the gap as the force reverses.
  double backlash_mm = 0.0;
  // Pulley runout (the identified periodic_position), quasi-static: the carriage reads
  // runout(x) = s sin(phi) + c (cos(phi) - 1), phi = 2 pi (x - reference) / period, ahead of the
  // motor, so the command moves by -runout(r). period 0: none.
  double runout_period_mm = 0.0;
  double runout_sin_mm = 0.0, runout_cos_mm = 0.0, runout_reference_mm = 0.0;
  // The carriage's travel per mm of steps (the identified scale_error's scale; 1: none), counted
  // from the point where the steps and the encoder were last referenced to each other.
  double travel_scale = 1.0;
  // A mode on the carriage that the two masses lack (the identified extra_resonance): its mass
  // on a spring-damper, in the model every design inverts (model::gantry_state_space). mass 0:
  // none.
  model::CarriageMode carriage_mode;
  // The driver's field lag, s, with params.c1_n_s_m damping the load angle: the motor follows
  // u (1 + T s) / (1 + field_lag s), T = c1 / k1, through Eq. 13, so the command is Eq. 13's
  // inverse times (1 + field_lag s) / (1 + T s) (Tustin, one state). 0: Eq. 13 itself.
  double field_lag_s = 0.0;
};

// The runout of m at carriage position x_mm, mm (0 without one).
double runout_mm(const GantryAxisLpvModel& m, double x_mm);

// Eq. 6 at carriage position x_mm, in N/m: direction > 0 for the belt pulling the carriage
// towards + (stretch x1 - x2 > 0: k_hat / (L - x)), < 0 towards - (k_hat / (L + x)), 0 the mean
// of the two, k_hat L / (L^2 - x^2). Without k_hat (<= 0): params.k2_n_m, along the travel by
// the compliance slope (k2 / (1 + s (x - reference))). Either way
// times 2 r / (1 + r) pulling + and 2 / (1 + r) pulling - (r = direction_ratio).
double belt_stiffness_n_m(const GantryAxisLpvModel& m, double x_mm, int direction = 0);

// The planned belt force on the carriage, N (Eq. 13 load side at the plan: m2 a + c2 v), from
// three consecutive reference samples (mm) T apart, centred on r0.
double planned_belt_force_n(const model::GantryAxisParams& p, double r_prev_mm, double r0_mm, double r_next_mm,
                            double period_s);

class GantryLpvFeedforward final : public Feedforward {
 public:
  // Joints 0 and 1 (x, y or the CoreXY motors) get a model; 2 and 3 pass through.
  static Result<std::unique_ptr<GantryLpvFeedforward>> create(const std::array<GantryAxisLpvModel, 2>& axes,
                                                              const LpvDesignOptions& opt);

  const char* name() const override { return "lpv"; }
  int preview_samples() const override { return P_; }
  void reset(const FeedforwardInput& at) override;
  void step(const FeedforwardInput& in, JointArray& u_mm) override;
  void rereference(const FeedforwardInput& at) override;
  bool load_offset(JointArray& mm) const override;
  bool inverts_model() const override { return true; }

 private:
  GantryLpvFeedforward() = default;
  void schedule_(int axis, double pos_mm, double force_n);
  // Friction force on the carriage at the planned position r_mm (advances the Dahl state).
  double friction_n_(int axis, double r_mm);
  int P_ = 0;
  double period_s_ = 1e-3;
  std::array<ScheduledPreviewInverse, 2> inv_;
  std::array<UniformGrid, 2> grid_;
  std::array<bool, 2> directional_{};       // table = [pulling - | pulling +] x grid
  std::array<double, 2> inv_force_{};       // 1 / F0
  std::array<model::GantryAxisParams, 2> params_{};
  std::array<GantryAxisLpvModel, 2> models_{};  // for K2(x, s) of the friction compensation
  std::array<double, 2> bristle_mm_{};      // Dahl state z
  std::array<double, 2> load_offset_mm_{};  // friction's and backlash's share of the last command
  std::array<double, 2> r_prev_{};          // r_{k-1}
  std::array<double, 2> scale_origin_mm_{};  // p: where steps and encoder were last referenced
  // The field lag's lead-lag (1 + tau s) / (1 + T s) (model/lead_lag.hpp) and its state.
  struct LeadLag {
    bool on = false;
    model::TustinLeadLag coef;
    double x_prev = 0.0, y_prev = 0.0;
  };
  std::array<LeadLag, 2> field_{};
  std::vector<JointArray> delay_;  // ring of the last P+1 inputs (pass-through joints)
  int head_ = 0;
};

}  // namespace feedloop::control
