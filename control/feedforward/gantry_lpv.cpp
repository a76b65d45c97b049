// Gantry LPV feedforward: grid design and the per-period step (see gantry_lpv.hpp).
#include "control/feedforward/gantry_lpv.hpp"

#include <algorithm>  // std::max, std::min
#include <cmath>      // std::isfinite

namespace feedloop::control {

double belt_stiffness_n_m(const GantryAxisLpvModel& m, double x_mm) {
  if (!(m.belt_unit_stiffness_n > 0.0)) return m.params.k2_n_m;
  const double L = m.pulley_distance_mm * 1e-3;
  const double x = std::clamp(x_mm * 1e-3, -0.8 * L, 0.8 * L);
  // Eq. 6 with x0 = 0: k_hat / (L - x) pulling +, k_hat / (L + x) pulling -; their mean.
  return m.belt_unit_stiffness_n * L / (L * L - x * x);
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
    const bool lpv = ax.belt_unit_stiffness_n > 0.0 && hi > lo;
    ff->grid_[a] = UniformGrid::span(lo, hi, lpv ? std::max(2, ax.grid_points) : 1);
    std::vector<PreviewInverse> table;
    for (int i = 0; i < ff->grid_[a].count; ++i) {
      model::GantryAxisParams p = ax.params;
      p.k2_n_m = belt_stiffness_n_m(ax, ff->grid_[a].at(i));  // Eq. 6 at this grid point
      auto d = discretize_for_hold(model::gantry_state_space(p), opt.period_s, opt.hold);  // Eq. 15
      if (!d) return Error{axis + ": " + d.error().message, {}};
      auto inv = design_preview_inverse(d.value(), opt.preview_samples, ref_offset, opt.weights);
      if (!inv) return Error{axis + ": " + inv.error().message, {}};
      table.push_back(std::move(inv.value()));
    }
    if (Status st = ff->inv_[a].configure(table, opt.hold); !st) return st.error();
  }
  ff->P_ = opt.preview_samples;
  ff->delay_.assign(static_cast<size_t>(ff->P_ + 1), JointArray{});
  return ff;
}

void GantryLpvFeedforward::schedule_(int axis, double pos_mm) {
  int idx[2];
  double w[2];
  const UniformGrid& g = grid_[static_cast<size_t>(axis)];
  g.locate(pos_mm, idx[0], w[1]);
  idx[1] = g.count > 1 ? idx[0] + 1 : idx[0];
  w[0] = 1.0 - w[1];
  inv_[static_cast<size_t>(axis)].schedule(idx, w, 2);
}

void GantryLpvFeedforward::reset(const FeedforwardInput& at) {
  for (int a = 0; a < 2; ++a) {
    schedule_(a, at.r_mm[static_cast<size_t>(a)]);
    inv_[static_cast<size_t>(a)].reset(&at.r_mm[static_cast<size_t>(a)]);
  }
  for (JointArray& j : delay_) j = at.r_mm;
  head_ = 0;
}

void GantryLpvFeedforward::step(const FeedforwardInput& in, JointArray& u_mm) {
  delay_[static_cast<size_t>(head_)] = in.r_mm;
  head_ = (head_ + 1) % (P_ + 1);
  u_mm = delay_[static_cast<size_t>(head_)];  // r_k for the pass-through joints
  for (int a = 0; a < 2; ++a) {
    ScheduledPreviewInverse& inv = inv_[static_cast<size_t>(a)];
    inv.push(&in.r_mm[static_cast<size_t>(a)]);
    schedule_(a, inv.reference(0, 0));  // the model at the carriage's planned position at t_k
    inv.step(&u_mm[static_cast<size_t>(a)]);
  }
}

}  // namespace feedloop::control
