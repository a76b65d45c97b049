// Config -> model-based LPV feedforward (see model_feedforward.hpp).
#include "control/feedforward/model_feedforward.hpp"

#include <cmath>  // std::floor, std::lround, std::isfinite
#include <string>

#include "control/feedforward/delta_lpv.hpp"
#include "control/feedforward/velocity_jump_smoother.hpp"

namespace feedloop::control {

model::GantryAxisParams gantry_params_from_config(const config::GantryModelConfig& g) {
  model::GantryAxisParams p;
  p.m1_kg = g.m1_kg;
  p.m2_kg = g.m2_kg;
  p.k1_n_m = g.k1_n_per_m;
  p.k2_n_m = g.k2_n_per_m;
  p.c1_n_s_m = g.c1_ns_per_m;
  p.c2_n_s_m = g.c2_ns_per_m;
  p.e_frac = g.stepper.belt_efficiency;
  return p;
}

model::DeltaParams delta_params_from_config(const config::DeltaLpvConfig& c, const config::DeltaGeometryConfig& g) {
  model::DeltaParams p;
  p.m_c_kg = c.m_c_kg;
  p.m_f_kg = c.m_f_kg;
  p.c_n_s_m = c.c_ns_per_m;
  p.b_n_s_m = c.b_ns_per_m;
  p.k_n_m = c.k_n_per_m;
  p.d0_per_s2 = c.d0_per_s2;
  p.d1_per_s = c.d1_per_s;
  p.d2_per_s = c.d2_per_s;
  p.m1_kg = c.m1_kg;
  p.m2_kg = c.m2_kg;
  p.b_x_n_s_m = c.b_x_ns_per_m;
  p.b_y_n_s_m = c.b_y_ns_per_m;
  p.b_z_n_s_m = c.b_z_ns_per_m;
  p.k_x_n_m = c.k_x_n_per_m;
  p.k_y_n_m = c.k_y_n_per_m;
  p.k_z_n_m = c.k_z_n_per_m;
  p.delta_x_mm = c.delta_x_mm;
  p.delta_y_mm = c.delta_y_mm;
  p.delta_z_mm = c.delta_z_mm;
  p.D_e_mm = c.d_e_mm;
  p.geometry.radius_mm = g.radius_mm;
  p.geometry.arm_length_mm = g.arm_length_mm;
  p.geometry.nozzle_offset_mm = g.nozzle_offset_mm;
  p.geometry.tower_angle_deg = {g.angle_a_deg, g.angle_b_deg, g.angle_c_deg};
  return p;
}

namespace {

// The model inverse alone (gantry or delta).
Result<std::unique_ptr<Feedforward>> model_inverse(const config::MachineConfig& cfg, double period_s,
                                                   bool freeze_at_centre) {
  if (!(period_s > 0.0) || !std::isfinite(period_s))
    return Error{"feedforward: servo period must be positive", {}};
  const double preview_ms = cfg.feedforward.lpv.preview_ms;
  LpvDesignOptions opt;
  opt.period_s = period_s;
  opt.preview_samples = static_cast<int>(std::lround(preview_ms * 1e-3 / period_s));
  if (!std::isfinite(preview_ms) || opt.preview_samples < 2)
    return Error{"feedforward.lpv.preview_ms = " + std::to_string(preview_ms) + " is shorter than 2 servo periods (" +
                     std::to_string(2e3 * period_s) + " ms)",
                 {}};

  if (cfg.kinematics == config::Kinematics::delta) {
    if (!cfg.delta) return Error{"feedforward lpv: a delta machine needs the 'delta' geometry section", {}};
    if (!cfg.model.delta_lpv)
      return Error{"feedforward lpv: the delta model section 'model.delta_lpv' is missing", {}};
    const config::DeltaGeometryConfig& g = *cfg.delta;
    DeltaLpvGrid grid;
    grid.xy_radius_mm = g.print_radius_mm;
    grid.z_min_mm = g.z_min_mm;
    grid.z_max_mm = g.z_max_mm;
    grid.freeze_at_centre = freeze_at_centre;
    const model::ForceTransform form = cfg.model.delta_lpv->force_transform == config::ForceTransform::virtual_work
                                           ? model::ForceTransform::VirtualWork
                                           : model::ForceTransform::Paper;
    auto ff = DeltaLpvFeedforward::create(delta_params_from_config(*cfg.model.delta_lpv, g), form, grid, opt,
                                          cfg.model.delta_lpv->gravity_m_s2);
    if (!ff) return ff.error();
    return std::unique_ptr<Feedforward>(std::move(ff.value()));
  }

  std::array<GantryAxisLpvModel, 2> axes;
  const char* names[2] = {"x", "y"};
  for (size_t a = 0; a < 2; ++a) {
    const config::GantryModelConfig* g = cfg.model.gantry_for(names[a]);
    if (g == nullptr)
      return Error{std::string("feedforward lpv: the model section 'model.gantry.") + names[a] + "' is missing", {}};
    GantryAxisLpvModel& m = axes[a];
    m.params = gantry_params_from_config(*g);
    m.belt_unit_stiffness_n = g->stepper.belt_unit_stiffness_n;
    m.pulley_distance_mm = g->stepper.pulley_distance_mm;
    m.coulomb_friction_n = g->coulomb_friction_n;
    if (const config::AxisConfig* ax = cfg.axis(names[a])) {
      m.min_mm = ax->min_mm;
      m.max_mm = ax->max_mm;
    }
  }
  auto ff = GantryLpvFeedforward::create(axes, opt);
  if (!ff) return ff.error();
  return std::unique_ptr<Feedforward>(std::move(ff.value()));
}

}  // namespace

Result<std::unique_ptr<Feedforward>> make_model_feedforward(const config::MachineConfig& cfg, double period_s,
                                                           bool freeze_at_centre) {
  auto inverse = model_inverse(cfg, period_s, freeze_at_centre);
  if (!inverse) return inverse;
  const config::LpvFeedforwardConfig& lpv = cfg.feedforward.lpv;
  const int half_width = static_cast<int>(std::floor(0.5 * (lpv.jump_window_ms * 1e-3 / period_s - 1.0) + 1e-9));
  if (!(lpv.jump_accel_mm_s2 > 0.0) || half_width < 1) return inverse;
  VelocityJumpSmoothing smoothing;
  smoothing.period_s = period_s;
  smoothing.max_accel_mm_s2 = lpv.jump_accel_mm_s2;
  smoothing.max_half_width = half_width;
  auto smoothed = VelocityJumpSmoother::create(std::move(inverse.value()), smoothing);
  if (!smoothed) return smoothed.error();
  return std::unique_ptr<Feedforward>(std::move(smoothed.value()));
}

}  // namespace feedloop::control
