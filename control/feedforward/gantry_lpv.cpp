// Gantry LPV feedforward: grid design and the per-period step (see gantry_lpv.hpp).
#include "control/feedforward/gantry_lpv.hpp"

#include <algorithm>  // std::max, std::min
#include <cmath>      // std::exp, std::isfinite, std::tanh
#include <numbers>    // std::numbers::pi

namespace feedloop::control {

double belt_stiffness_n_m(const GantryAxisLpvModel& m, double x_mm, int direction) {
  // A constant ratio r between the directions about their mean (the identified
  // direction_dependent_stiffness: K+ = 2 r k2 / (1 + r), K- = 2 k2 / (1 + r)).
  const double r = m.direction_ratio;
  const double dir_factor = direction > 0   ? 2.0 * r / (1.0 + r)
                            : direction < 0 ? 2.0 / (1.0 + r)
                                            : 1.0;
  if (!(m.belt_unit_stiffness_n > 0.0))
    return m.params.k2_n_m * dir_factor *
           model::belt_stiffness_factor(m.compliance_slope_per_m, m.stiffness_reference_mm, x_mm);
  const double L = m.pulley_distance_mm * 1e-3;
  const double x = std::clamp(x_mm * 1e-3, -0.8 * L, 0.8 * L);
  // Eq. 6 with x0 = 0: k_hat / (L - x) pulling +, k_hat / (L + x) pulling -; or their mean.
  if (direction > 0) return dir_factor * m.belt_unit_stiffness_n / (L - x);
  if (direction < 0) return dir_factor * m.belt_unit_stiffness_n / (L + x);
  return m.belt_unit_stiffness_n * L / (L * L - x * x);
}

double runout_mm(const GantryAxisLpvModel& m, double x_mm) {
  if (!(m.runout_period_mm > 0.0)) return 0.0;
  const double phi = 2.0 * std::numbers::pi * (x_mm - m.runout_reference_mm) / m.runout_period_mm;
  return m.runout_sin_mm * std::sin(phi) + m.runout_cos_mm * (std::cos(phi) - 1.0);
}

double planned_belt_force_n(const model::GantryAxisParams& p, double r_prev_mm, double r0_mm, double r_next_mm,
                            double period_s) {
  const double v = (r_next_mm - r_prev_mm) * 1e-3 / (2.0 * period_s);
  const double a = (r_next_mm - 2.0 * r0_mm + r_prev_mm) * 1e-3 / (period_s * period_s);
  return p.m2_kg * a + p.c2_n_s_m * v;
}

Result<std::unique_ptr<GantryLpvFeedforward>> GantryLpvFeedforward::create(
    const std::array<GantryAxisLpvModel, 2>& axes, const LpvDesignOptions& opt) {
  std::unique_ptr<GantryLpvFeedforward> ff(new GantryLpvFeedforward());
  const int ref_offset = opt.hold == CommandHold::linear ? 1 : 0;
  for (size_t a = 0; a < 2; ++a) {
    const GantryAxisLpvModel& ax = axes[a];
    const std::string axis = a == 0 ? "joint 0 (x)" : "joint 1 (y)";
    if (Status st = model::validate(ax.params); !st) return Error{axis + ": " + st.error().message, {}};
    if (!(ax.pulley_distance_mm > 0.0)) return Error{axis + ": pulley_distance_mm must be > 0", {}};
    double lo = ax.min_mm, hi = ax.max_mm;
    const double lim = 0.8 * ax.pulley_distance_mm;
    lo = std::isfinite(lo) ? std::max(lo, -lim) : -lim;
    hi = std::isfinite(hi) ? std::min(hi, lim) : lim;
    if (!(hi >= lo)) return Error{axis + ": empty travel for the feedforward grid", {}};
    if (!(ax.direction_ratio >= 0.1 && ax.direction_ratio <= 10.0))
      return Error{axis + ": direction_ratio must be within 0.1-10", {}};
    if (!std::isfinite(ax.compliance_slope_per_m) || !std::isfinite(ax.stiffness_reference_mm))
      return Error{axis + ": the belt's compliance slope and reference must be finite", {}};
    // A position grid for Eq. 6 or for the calibrated belt's slope.
    const bool lpv =
        (ax.belt_unit_stiffness_n > 0.0 || ax.compliance_slope_per_m != 0.0) && hi > lo;
    // Two directions for Eq. 6 or for a ratio of its own.
    const bool directional = (lpv || ax.direction_ratio != 1.0) && ax.direction_scheduled;
    if (directional && !(ax.direction_force_n > 0.0 && std::isfinite(ax.direction_force_n)))
      return Error{axis + ": direction_force_n must be > 0 and finite", {}};
    ff->grid_[a] = UniformGrid::span(lo, hi, lpv ? std::max(2, ax.grid_points) : 1);
    ff->directional_[a] = directional;
    ff->inv_force_[a] = directional ? 1.0 / ax.direction_force_n : 0.0;
    ff->params_[a] = ax.params;
    if (!(ax.coulomb_friction_n >= 0.0 && std::isfinite(ax.coulomb_friction_n)))
      return Error{axis + ": coulomb_friction_n must be >= 0 and finite", {}};
    if (ax.coulomb_friction_n > 0.0 && !(ax.friction_bristle_mm > 0.0 && std::isfinite(ax.friction_bristle_mm)))
      return Error{axis + ": friction_bristle_mm must be > 0 and finite", {}};
    if (!(ax.backlash_mm >= 0.0 && std::isfinite(ax.backlash_mm)))
      return Error{axis + ": backlash_mm must be >= 0 and finite", {}};
    if (!(ax.runout_period_mm >= 0.0 && std::isfinite(ax.runout_period_mm) &&
          std::isfinite(ax.runout_sin_mm) && std::isfinite(ax.runout_cos_mm) &&
          std::isfinite(ax.runout_reference_mm)))
      return Error{axis + ": the runout must be finite, its period >= 0", {}};
    if (!(ax.travel_scale >= 0.5 && ax.travel_scale <= 2.0))
      return Error{axis + ": travel_scale must be within 0.5-2", {}};
    if (!(ax.field_lag_s >= 0.0 && ax.field_lag_s <= 0.1))
      return Error{axis + ": field_lag_s must be within 0-0.1 s", {}};
    if (ax.field_lag_s > 0.0 &&
        !(ax.params.c1_n_s_m / ax.params.k1_n_m >= model::kMinFieldDampingLagS))
      return Error{axis + ": a field lag needs c1 / k1 >= 0.01 ms (c1 damps the load angle)", {}};
    if (ax.field_lag_s > 0.0) {
      // (1 + tau s) / (1 + T s) at the servo period, T = c1 / k1 (model/lead_lag.hpp).
      LeadLag& f = ff->field_[a];
      f.on = true;
      f.coef = model::tustin_lead_lag(ax.field_lag_s, ax.params.c1_n_s_m / ax.params.k1_n_m,
                                      opt.period_s);
    }
    if (Status st = model::validate(ax.carriage_mode); !st)
      return Error{axis + ": " + st.error().message, {}};
    if (ax.backlash_mm > 0.0 &&
        !(ax.direction_force_n > 0.0 && std::isfinite(ax.direction_force_n)))
      return Error{axis + ": direction_force_n must be > 0 and finite", {}};
    ff->models_[a] = ax;
    std::vector<PreviewInverse> table;
    // Directional: designs 0..G-1 pulling - (K2 = k_hat / (L + x)), G..2G-1 pulling + (G = 1
    // without Eq. 6).
    const int directions[2] = {-1, +1};
    for (int dir = 0; dir < (directional ? 2 : 1); ++dir) {
      for (int i = 0; i < ff->grid_[a].count; ++i) {
        model::GantryAxisParams p = ax.params;
        // Eq. 6 at this grid point (and direction, or the mean of both).
        p.k2_n_m = belt_stiffness_n_m(ax, ff->grid_[a].at(i), directional ? directions[dir] : 0);
        auto d = discretize_for_hold(model::gantry_state_space(p, ax.carriage_mode), opt.period_s,
                                     opt.hold);  // Eq. 15
        if (!d) return Error{axis + ": " + d.error().message, {}};
        auto inv = design_preview_inverse(d.value(), opt.preview_samples, ref_offset, opt.weights);
        if (!inv) return Error{axis + ": " + inv.error().message, {}};
        table.push_back(std::move(inv.value()));
      }
    }
    if (Status st = ff->inv_[a].configure(table, opt.hold); !st) return st.error();
  }
  ff->P_ = opt.preview_samples;
  ff->period_s_ = opt.period_s;
  ff->delay_.assign(static_cast<size_t>(ff->P_ + 1), JointArray{});
  return ff;
}

void GantryLpvFeedforward::schedule_(int axis, double pos_mm, double force_n) {
  const size_t a = static_cast<size_t>(axis);
  int idx[4];
  double w[4];
  const UniformGrid& g = grid_[a];
  double wx = 0.0;
  g.locate(pos_mm, idx[0], wx);
  idx[1] = g.count > 1 ? idx[0] + 1 : idx[0];
  w[0] = 1.0 - wx;
  w[1] = wx;
  if (!directional_[a]) {
    inv_[a].schedule(idx, w, 2);
    return;
  }
  // Bilinear: position x direction, w+ = 0.5 + 0.5 tanh(F / F0) on the designs pulling +.
  const double wp = 0.5 + 0.5 * std::tanh(force_n * inv_force_[a]);
  idx[2] = idx[0] + g.count;
  idx[3] = idx[1] + g.count;
  w[2] = w[0] * wp;
  w[3] = w[1] * wp;
  w[0] *= 1.0 - wp;
  w[1] *= 1.0 - wp;
  inv_[a].schedule(idx, w, 4);
}

bool GantryLpvFeedforward::load_offset(JointArray& mm) const {
  mm = {load_offset_mm_[0], load_offset_mm_[1], 0.0, 0.0};
  return models_[0].coulomb_friction_n > 0.0 || models_[1].coulomb_friction_n > 0.0 ||
         models_[0].backlash_mm > 0.0 || models_[1].backlash_mm > 0.0 ||
         models_[0].runout_period_mm > 0.0 || models_[1].runout_period_mm > 0.0 ||
         models_[0].travel_scale != 1.0 || models_[1].travel_scale != 1.0;
}

void GantryLpvFeedforward::rereference(const FeedforwardInput& at) {
  for (size_t a = 0; a < 2; ++a) scale_origin_mm_[a] = at.r_mm[a];
}

double GantryLpvFeedforward::friction_n_(int axis, double r_mm) {
  const size_t a = static_cast<size_t>(axis);
  const GantryAxisLpvModel& m = models_[a];
  const double dr = r_mm - r_prev_[a];  // r_{k-1}: step() moves it on after this
  double& z = bristle_mm_[a];
  // Dahl, exact over a step of constant direction: z -> s z_max - (s z_max - z) exp(-|dr| / z_max).
  if (dr != 0.0) {
    const double target = dr > 0.0 ? m.friction_bristle_mm : -m.friction_bristle_mm;
    z = target - (target - z) * std::exp(-std::abs(dr) / m.friction_bristle_mm);
  }
  return m.coulomb_friction_n * z / m.friction_bristle_mm;
}

void GantryLpvFeedforward::reset(const FeedforwardInput& at) {
  for (int a = 0; a < 2; ++a) {
    const size_t as = static_cast<size_t>(a);
    bristle_mm_[as] = 0.0;  // at rest: the friction holds no force
    load_offset_mm_[as] = 0.0;
    schedule_(a, at.r_mm[as], 0.0);
    inv_[as].reset(&at.r_mm[as]);
    r_prev_[as] = at.r_mm[as];
    field_[as].x_prev = field_[as].y_prev = at.r_mm[as];
  }
  for (JointArray& j : delay_) j = at.r_mm;
  head_ = 0;
}

void GantryLpvFeedforward::step(const FeedforwardInput& in, JointArray& u_mm) {
  delay_[static_cast<size_t>(head_)] = in.r_mm;
  head_ = (head_ + 1) % (P_ + 1);
  u_mm = delay_[static_cast<size_t>(head_)];  // r_k for the pass-through joints
  for (int a = 0; a < 2; ++a) {
    const size_t as = static_cast<size_t>(a);
    ScheduledPreviewInverse& inv = inv_[as];
    inv.push(&in.r_mm[as]);
    const double r0 = inv.reference(0, 0);
    // The model at the carriage's planned position at t_k and the planned belt force's direction.
    const GantryAxisLpvModel& model = models_[as];
    const double friction_n = model.coulomb_friction_n > 0.0 ? friction_n_(a, r0) : 0.0;
    const double f =
        directional_[as] || model.backlash_mm > 0.0
            ? planned_belt_force_n(params_[as], r_prev_[as], r0, inv.reference(1, 0), period_s_) +
                  friction_n
            : 0.0;
    schedule_(a, r0, directional_[as] ? f : 0.0);
    inv.step(&u_mm[as]);
    load_offset_mm_[as] = 0.0;
    if (model.backlash_mm > 0.0) {
      // Across the dead band on the side the planned force pulls from (the pulley leads the belt
      // by w / 2 while it pulls +, lags by w / 2 while it pulls -, centred at rest).
      load_offset_mm_[as] = 0.5 * model.backlash_mm * std::tanh(f / model.direction_force_n);
      u_mm[as] += load_offset_mm_[as];
    }
    if (friction_n != 0.0) {
      // Static compliance of motor and belt in series, the belt at the scheduled stretch direction.
      const double wp = directional_[as] ? 0.5 + 0.5 * std::tanh(f * inv_force_[as]) : 0.5;
      const double inv_k2 =
          wp / belt_stiffness_n_m(model, r0, +1) + (1.0 - wp) / belt_stiffness_n_m(model, r0, -1);
      const double friction_mm = friction_n * (1.0 / params_[as].k1_n_m + inv_k2) * 1e3;
      load_offset_mm_[as] += friction_mm;
      u_mm[as] += friction_mm;
    }
    if (model.runout_period_mm > 0.0) {
      // The carriage reads runout(x) ahead of the motor: the motor goes to r - runout(r).
      const double runout = runout_mm(model, r0);
      load_offset_mm_[as] -= runout;
      u_mm[as] -= runout;
    }
    if (model.travel_scale != 1.0) {
      // The carriage travels s mm per mm of steps from p: the motor goes to p + (u - p) / s.
      const double p = scale_origin_mm_[as];
      const double scaled = p + (u_mm[as] - p) / model.travel_scale;
      load_offset_mm_[as] += scaled - u_mm[as];
      u_mm[as] = scaled;
    }
    if (field_[as].on) {
      // The field lags the command: command what makes the field follow Eq. 13's inverse.
      LeadLag& lag = field_[as];
      const double y = lag.coef.b0 * u_mm[as] + lag.coef.b1 * lag.x_prev - lag.coef.a1 * lag.y_prev;
      lag.x_prev = u_mm[as];
      lag.y_prev = y;
      u_mm[as] = y;
    }
    r_prev_[as] = r0;
  }
}

}  // namespace feedloop::control
