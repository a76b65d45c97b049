// Config -> control parameter structs (see control_config.hpp).
#include "engine/control_config.hpp"

#include <array>
#include <cmath>  // std::floor, std::lround, std::isfinite

#include "control/feedforward/delta_lpv.hpp"
#include "control/feedforward/gantry_lpv.hpp"
#include "control/feedforward/velocity_jump_smoother.hpp"

namespace feedloop::engine {

control::PiParams pi_params_from_config(const config::ControlConfig& control,
                                        const std::string& axis, double period_s) {
  const config::AxisGainsConfig gains = control.gains_for(axis);
  control::PiParams p;
  p.kp = gains.kp;
  p.ki_per_s = gains.ki_per_s;
  p.period_s = period_s;
  p.max_correction_mm_s = control.max_correction_mm_s;
  return p;
}

control::LostStepParams lost_step_params_from_config(const config::ControlConfig& control,
                                                     double full_step_mm) {
  control::LostStepParams p;
  p.threshold_mm = control.skipped_step_threshold_mm;
  p.full_step_mm = full_step_mm;
  return p;
}

control::EncoderGuardParams encoder_guard_params_from_config(const config::MachineConfig& cfg,
                                                             const std::string& axis) {
  control::EncoderGuardParams p;
  p.axis = axis;
  const config::AxisConfig* a = cfg.axis(axis);
  const double v_max_mm_s = a != nullptr ? a->max_velocity_mm_s : cfg.planner.max_velocity_mm_s;
  p.max_speed_mm_s = 2.0 * v_max_mm_s;
  p.jump_margin_mm = cfg.control.max_encoder_jump_mm;
  p.reject_limit = 3;
  p.max_following_error_mm = cfg.control.max_following_error_mm;
  // Samples may be missing for ten servo periods while moving (the host loop asks for one each).
  p.stale_s = 10.0 / cfg.servo.rate_hz;
  return p;
}

control::ShaperType shaper_type(config::ShaperType type) {
  switch (type) {
    case config::ShaperType::zv:
      return control::ShaperType::zv;
    case config::ShaperType::mzv:
      return control::ShaperType::mzv;
    case config::ShaperType::ei:
      return control::ShaperType::ei;
  }
  return control::ShaperType::mzv;
}

Result<control::InputShaperSetup> input_shaper_setup(const config::ShaperConfig& shaper,
                                                     const planner::Kinematics& kinematics,
                                                     double period_s) {
  control::InputShaperSetup setup;
  setup.period_s = period_s;
  auto impulses_of = [&](const std::string& axis) -> Result<control::Impulses> {
    const config::AxisShaperConfig a = shaper.for_axis(axis);
    auto r = control::make_impulses(shaper_type(a.type), a.freq_hz, a.damping);
    if (!r.ok()) return Error{"axis " + axis + ": " + r.error().message, {}};
    return r;
  };
  if (kinematics.is_linear()) {
    setup.linear_map = kinematics.linear_map();
    for (int j = 0; j < 2; ++j) {  // x and y; z passes through
      auto r = impulses_of(j == 0 ? "x" : "y");
      if (!r.ok()) return r.error();
      setup.shapers[j] = *r;
    }
  } else {
    static const std::array<std::string, 3> kCarriages = {"A", "B", "C"};
    for (int j = 0; j < 3; ++j) {
      auto r = impulses_of(kCarriages[j]);
      if (!r.ok()) return r.error();
      setup.shapers[j] = *r;
    }
  }
  return setup;
}

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

model::DeltaParams delta_params_from_config(const config::DeltaLpvConfig& c,
                                            const config::DeltaGeometryConfig& g) {
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
Result<std::unique_ptr<control::Feedforward>> model_inverse(const config::MachineConfig& cfg,
                                                            double period_s,
                                                            bool freeze_at_centre) {
  if (!(period_s > 0.0) || !std::isfinite(period_s))
    return Error{"feedforward: servo period must be positive", {}};
  const double preview_ms = cfg.feedforward.lpv.preview_ms;
  control::LpvDesignOptions opt;
  opt.period_s = period_s;
  opt.preview_samples = static_cast<int>(std::lround(preview_ms * 1e-3 / period_s));
  if (!std::isfinite(preview_ms) || opt.preview_samples < 2)
    return Error{"feedforward.lpv.preview_ms = " + std::to_string(preview_ms) +
                     " is shorter than 2 servo periods (" + std::to_string(2e3 * period_s) + " ms)",
                 {}};

  if (cfg.kinematics == config::Kinematics::delta) {
    if (!cfg.delta)
      return Error{"feedforward lpv: a delta machine needs the 'delta' geometry section", {}};
    if (!cfg.model.delta_lpv)
      return Error{"feedforward lpv: the delta model section 'model.delta_lpv' is missing", {}};
    const config::DeltaGeometryConfig& g = *cfg.delta;
    control::DeltaLpvGrid grid;
    grid.xy_radius_mm = g.print_radius_mm;
    grid.z_min_mm = g.z_min_mm;
    grid.z_max_mm = g.z_max_mm;
    grid.freeze_at_centre = freeze_at_centre;
    const model::ForceTransform form =
        cfg.model.delta_lpv->force_transform == config::ForceTransform::virtual_work
            ? model::ForceTransform::VirtualWork
            : model::ForceTransform::Paper;
    auto ff =
        control::DeltaLpvFeedforward::create(delta_params_from_config(*cfg.model.delta_lpv, g),
                                             form, grid, opt, cfg.model.delta_lpv->gravity_m_s2);
    if (!ff) return ff.error();
    return std::unique_ptr<control::Feedforward>(std::move(ff.value()));
  }

  std::array<control::GantryAxisLpvModel, 2> axes;
  const char* names[2] = {"x", "y"};
  for (size_t a = 0; a < 2; ++a) {
    const config::GantryModelConfig* g = cfg.model.gantry_for(names[a]);
    if (g == nullptr)
      return Error{std::string("feedforward lpv: the model section 'model.gantry.") + names[a] +
                       "' is missing",
                   {}};
    control::GantryAxisLpvModel& m = axes[a];
    m.params = gantry_params_from_config(*g);
    m.belt_unit_stiffness_n = g->stepper.belt_unit_stiffness_n;
    m.pulley_distance_mm = g->stepper.pulley_distance_mm;
    m.coulomb_friction_n = g->coulomb_friction_n;
    m.friction_bristle_mm = g->friction_bristle_mm;
    m.backlash_mm = g->backlash_mm;
    m.direction_ratio = g->belt_direction_ratio;
    m.compliance_slope_per_m = g->belt_compliance_slope_per_m;
    m.stiffness_reference_mm = g->belt_stiffness_reference_mm;
    m.runout_period_mm = g->runout_period_mm;
    m.runout_sin_mm = g->runout_sin_um * 1e-3;
    m.runout_cos_mm = g->runout_cos_um * 1e-3;
    m.runout_reference_mm = g->runout_reference_mm;
    m.travel_scale = g->travel_scale;
    m.carriage_mode = {g->extra_resonance_hz, g->extra_resonance_damping,
                       g->extra_resonance_mass_kg};
    m.field_lag_s = g->field_lag_ms * 1e-3;
    if (const config::AxisConfig* ax = cfg.axis(names[a])) {
      m.min_mm = ax->min_mm;
      m.max_mm = ax->max_mm;
    }
  }
  auto ff = control::GantryLpvFeedforward::create(axes, opt);
  if (!ff) return ff.error();
  return std::unique_ptr<control::Feedforward>(std::move(ff.value()));
}

}  // namespace

Result<std::unique_ptr<control::Feedforward>> make_model_feedforward(
    const config::MachineConfig& cfg, double period_s, bool freeze_at_centre) {
  auto inverse = model_inverse(cfg, period_s, freeze_at_centre);
  if (!inverse) return inverse;
  const config::LpvFeedforwardConfig& lpv = cfg.feedforward.lpv;
  const int half_width =
      static_cast<int>(std::floor(0.5 * (lpv.jump_window_ms * 1e-3 / period_s - 1.0) + 1e-9));
  if (!(lpv.jump_accel_mm_s2 > 0.0) || half_width < 1) return inverse;
  control::VelocityJumpSmoothing smoothing;
  smoothing.period_s = period_s;
  smoothing.max_accel_mm_s2 = lpv.jump_accel_mm_s2;
  smoothing.max_half_width = half_width;
  auto smoothed = control::VelocityJumpSmoother::create(std::move(inverse.value()), smoothing);
  if (!smoothed) return smoothed.error();
  return std::unique_ptr<control::Feedforward>(std::move(smoothed.value()));
}

}  // namespace feedloop::engine
