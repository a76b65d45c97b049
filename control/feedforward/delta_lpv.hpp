// Model-based LPV feedforward for a delta printer: the preview inverse (preview_design.hpp) of the
// full 3x3 model of the delta paper, Eq. 29, G(s) = [I - G_Fq T W(s) Jbar]^-1 G_qd(s), from
// commanded to actual carriage positions (model/delta_lpv.hpp, its 18-state realisation). The
// inverse is MIMO on the coupled model (no term-by-term inversion); the non-minimum-phase
// carriage zero (Eq. 34, d1 < 0: +674 rad/s) is handled by the preview.
// LPV: designs on a grid of nozzle positions (x, y over the print disc, z over the height),
// trilinearly interpolated at the planned nozzle position at t_k every period.
// freeze_at_centre: the model at (0, 0, z) only (the "fixed centre model" of the benchmarks;
// still scheduled on z). The extruder joint passes through, delayed by P periods.
// The effector's weight (not in Eq. 29, a model linearised about a point): the carriages carry
// tau = J(X)^T [0, 0, -(m1 + m2) g] (virtual work, Eq. 12), which stretches each belt by tau_i / k.
// Its share moves between the carriages as the effector moves off the centre (where the three
// shares are equal: a uniform stretch is a z offset that calibration absorbs), so the LPV
// feedforward adds -(tau_i(X) - tau_i(0, 0, z)) / k at the planned position; the fixed centre model
// adds nothing (its model is the centre's).
#pragma once

#include <array>
#include <memory>
#include <vector>

#include "control/feedforward.hpp"
#include "control/feedforward/lpv_options.hpp"
#include "control/feedforward/scheduled_inverse.hpp"
#include "core/result.hpp"
#include "model/delta_lpv.hpp"

namespace feedloop::control {

struct DeltaLpvGrid {
  double xy_radius_mm = 100.0;  // grid covers [-r, r]^2; points beyond the disc of radius r use
                                // the model at their projection onto it
  double xy_step_mm = 25.0;
  double z_min_mm = 0.0;
  double z_max_mm = 250.0;
  double z_step_mm = 50.0;
  bool freeze_at_centre = false;  // model at (0, 0, z) only
};

class DeltaLpvFeedforward final : public Feedforward {
 public:
  static Result<std::unique_ptr<DeltaLpvFeedforward>> create(const model::DeltaParams& params,
                                                             model::ForceTransform form, const DeltaLpvGrid& grid,
                                                             const LpvDesignOptions& opt, double gravity_m_s2 = 0.0);

  const char* name() const override { return frozen_ ? "lpv-centre" : "lpv"; }
  int preview_samples() const override { return P_; }
  void reset(const FeedforwardInput& at) override;
  void step(const FeedforwardInput& in, JointArray& u_mm) override;
  bool load_offset(JointArray& mm) const override;
  bool inverts_model() const override { return true; }

  int grid_points() const { return inv_.points(); }

 private:
  DeltaLpvFeedforward() = default;
  void schedule_(const std::array<double, 3>& nozzle_mm);
  // The belt stretch of the effector's weight at X relative to the centre at the same height, mm.
  void add_weight_(const std::array<double, 3>& nozzle_mm, JointArray& u_mm);
  JointArray weight_mm_{};      // the weight's share of the last command
  model::DeltaGeometry geometry_;
  double weight_n_ = 0.0;       // (m1 + m2) g; 0: no weight term
  double belt_k_n_m_ = 1.0;     // k of the carriage's belt
  int P_ = 0;
  bool frozen_ = false;
  ScheduledPreviewInverse inv_;
  UniformGrid gx_, gy_, gz_;
  std::vector<FeedforwardInput> delay_;  // ring of the last P+1 inputs (extruder, nozzle at t_k)
  int head_ = 0;
};

}  // namespace feedloop::control
