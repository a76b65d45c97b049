// Model-based LPV feedforward for a Cartesian or CoreXY machine: per X and Y joint, the preview
// inverse (preview_design.hpp) of the thesis's two-mass stepper + belt model (closed-loop-gantry
// thesis, Eq. 13-16) whose belt stiffness depends on the carriage position (Eq. 5-6):
//   K2(x) = k_hat / (L - x sgn(stretch))   ->   direction average  K2(x) = k_hat L / (L^2 - x^2)
// (x0 = 0: K2(0) = k_hat / L). The direction dependence is NOT modelled (it is a switching
// nonlinearity; the simulator has it, docs/feedforward.md). Designs are precomputed on a grid
// over the travel and interpolated at the reference position r_k every period (LPV).
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

namespace feedloop::control {

struct GantryAxisLpvModel {
  model::GantryAxisParams params;     // Eq. 13; params.k2_n_m is replaced by K2(x) at each grid point
  double belt_unit_stiffness_n = 0;   // k_hat of Eq. 6; <= 0: constant k2 (no position dependence)
  double pulley_distance_mm = 300.0;  // L of Eq. 6
  double min_mm = -100.0;             // travel covered by the grid (clamped to |x| <= 0.8 L)
  double max_mm = 100.0;
  int grid_points = 25;
};

// Eq. 6 averaged over the two directions, in N/m, at carriage position x_mm.
double belt_stiffness_n_m(const GantryAxisLpvModel& m, double x_mm);

class GantryLpvFeedforward final : public Feedforward {
 public:
  // Joints 0 and 1 (x, y or the CoreXY motors) get a model; 2 and 3 pass through.
  static Result<std::unique_ptr<GantryLpvFeedforward>> create(const std::array<GantryAxisLpvModel, 2>& axes,
                                                              const LpvDesignOptions& opt);

  const char* name() const override { return "lpv"; }
  int preview_samples() const override { return P_; }
  void reset(const FeedforwardInput& at) override;
  void step(const FeedforwardInput& in, JointArray& u_mm) override;

 private:
  GantryLpvFeedforward() = default;
  void schedule_(int axis, double pos_mm);
  int P_ = 0;
  std::array<ScheduledPreviewInverse, 2> inv_;
  std::array<UniformGrid, 2> grid_;
  std::vector<JointArray> delay_;  // ring of the last P+1 inputs (pass-through joints)
  int head_ = 0;
};

}  // namespace feedloop::control
