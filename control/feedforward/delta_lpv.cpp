// Delta LPV feedforward: grid design over the workspace and the per-period step (see delta_lpv.hpp).
#include "control/feedforward/delta_lpv.hpp"

#include <algorithm>  // std::max
#include <cmath>      // std::ceil, std::hypot, std::isfinite
#include <string>

#include "model/delta_lpv.hpp"

namespace feedloop::control {

namespace {
int points_for(double lo, double hi, double step) {
  if (!(hi > lo) || !(step > 0.0)) return 1;
  return std::max(2, static_cast<int>(std::ceil((hi - lo) / step - 1e-9)) + 1);
}
}  // namespace

Result<std::unique_ptr<DeltaLpvFeedforward>> DeltaLpvFeedforward::create(const model::DeltaParams& params,
                                                                         model::ForceTransform form,
                                                                         const DeltaLpvGrid& grid,
                                                                         const LpvDesignOptions& opt,
                                                                         double gravity_m_s2) {
  auto mdl = model::DeltaLpvModel::create(params, form);
  if (!mdl) return Error{"delta feedforward: " + mdl.error().message, {}};
  if (!(grid.z_max_mm >= grid.z_min_mm)) return Error{"delta feedforward: z_max_mm < z_min_mm", {}};
  std::unique_ptr<DeltaLpvFeedforward> ff(new DeltaLpvFeedforward());
  ff->frozen_ = grid.freeze_at_centre;
  if (!(gravity_m_s2 >= 0.0 && std::isfinite(gravity_m_s2))) return Error{"delta feedforward: gravity must be >= 0", {}};
  ff->geometry_ = params.geometry;
  ff->weight_n_ = grid.freeze_at_centre ? 0.0 : (params.m1_effective_kg() + params.m2_kg) * gravity_m_s2;
  ff->belt_k_n_m_ = params.k_n_m;
  const double r = grid.freeze_at_centre ? 0.0 : std::max(0.0, grid.xy_radius_mm);
  ff->gx_ = UniformGrid::span(-r, r, points_for(-r, r, grid.xy_step_mm));
  ff->gy_ = ff->gx_;
  ff->gz_ = UniformGrid::span(grid.z_min_mm, grid.z_max_mm, points_for(grid.z_min_mm, grid.z_max_mm, grid.z_step_mm));

  const int ref_offset = opt.hold == CommandHold::linear ? 1 : 0;
  std::vector<PreviewInverse> table;
  table.reserve(static_cast<size_t>(ff->gx_.count * ff->gy_.count * ff->gz_.count));
  for (int iz = 0; iz < ff->gz_.count; ++iz)
    for (int iy = 0; iy < ff->gy_.count; ++iy)
      for (int ix = 0; ix < ff->gx_.count; ++ix) {
        Eigen::Vector3d pos(ff->gx_.at(ix), ff->gy_.at(iy), ff->gz_.at(iz));
        const double rad = std::hypot(pos.x(), pos.y());
        if (rad > r && rad > 0.0) pos.head<2>() *= r / rad;  // corner of the square: the disc's edge
        auto op = mdl->at(pos);
        if (!op) return Error{"delta feedforward grid: " + op.error().message, {}};
        auto ss = mdl->state_space(op.value());  // Eq. 29 at X-bar, SI
        if (!ss) return Error{"delta feedforward: " + ss.error().message, {}};
        auto d = discretize_for_hold(ss.value(), opt.period_s, opt.hold);
        if (!d) return Error{"delta feedforward: " + d.error().message, {}};
        auto inv = design_preview_inverse(d.value(), opt.preview_samples, ref_offset, opt.weights);
        if (!inv)
          return Error{"delta feedforward at (" + std::to_string(pos.x()) + ", " + std::to_string(pos.y()) + ", " +
                           std::to_string(pos.z()) + ") mm: " + inv.error().message,
                       {}};
        table.push_back(std::move(inv.value()));
      }
  if (Status st = ff->inv_.configure(table, opt.hold); !st) return st.error();
  ff->P_ = opt.preview_samples;
  ff->delay_.assign(static_cast<size_t>(ff->P_ + 1), FeedforwardInput{});
  return ff;
}

void DeltaLpvFeedforward::schedule_(const std::array<double, 3>& nozzle_mm) {
  int ix, iy, iz;
  double wx, wy, wz;
  gx_.locate(nozzle_mm[0], ix, wx);
  gy_.locate(nozzle_mm[1], iy, wy);
  gz_.locate(nozzle_mm[2], iz, wz);
  int idx[8];
  double w[8];
  int c = 0;
  for (int dz = 0; dz < 2; ++dz)
    for (int dy = 0; dy < 2; ++dy)
      for (int dx = 0; dx < 2; ++dx) {
        const int jx = std::min(ix + dx, gx_.count - 1);
        const int jy = std::min(iy + dy, gy_.count - 1);
        const int jz = std::min(iz + dz, gz_.count - 1);
        idx[c] = (jz * gy_.count + jy) * gx_.count + jx;
        w[c] = (dx ? wx : 1.0 - wx) * (dy ? wy : 1.0 - wy) * (dz ? wz : 1.0 - wz);
        ++c;
      }
  inv_.schedule(idx, w, 8);
}

void DeltaLpvFeedforward::reset(const FeedforwardInput& at) {
  schedule_(at.nozzle_mm);
  inv_.reset(at.r_mm.data());
  for (FeedforwardInput& d : delay_) d = at;
  head_ = 0;
}

void DeltaLpvFeedforward::step(const FeedforwardInput& in, JointArray& u_mm) {
  delay_[static_cast<size_t>(head_)] = in;
  head_ = (head_ + 1) % (P_ + 1);
  const FeedforwardInput& now = delay_[static_cast<size_t>(head_)];  // the plan at t_k
  u_mm[3] = now.r_mm[3];
  inv_.push(in.r_mm.data());  // carriages A, B, C
  schedule_(now.nozzle_mm);
  inv_.step(u_mm.data());
  add_weight_(now.nozzle_mm, u_mm);
}

bool DeltaLpvFeedforward::load_offset(JointArray& mm) const {
  mm = weight_mm_;
  return weight_n_ > 0.0;
}

void DeltaLpvFeedforward::add_weight_(const std::array<double, 3>& nozzle_mm, JointArray& u_mm) {
  weight_mm_ = JointArray{};
  if (!(weight_n_ > 0.0)) return;
  const Eigen::Vector3d x(nozzle_mm[0], nozzle_mm[1], nozzle_mm[2]);
  auto j = model::jacobian(geometry_, x);
  auto j0 = model::jacobian(geometry_, Eigen::Vector3d(0.0, 0.0, x.z()));
  if (!j || !j0) return;  // out of reach: the inverse's own schedule clamps; no weight term there
  // tau = J^T F with F = [0, 0, -W]: the third row of J, times -W.
  const Eigen::Vector3d tau = -weight_n_ * j.value().row(2).transpose();
  const Eigen::Vector3d tau0 = -weight_n_ * j0.value().row(2).transpose();
  // Carriage i sags by -tau_i / k (tau_i < 0 pulls it down): command it up by as much.
  for (int i = 0; i < 3; ++i) {
    weight_mm_[static_cast<size_t>(i)] = -(tau[i] - tau0[i]) / belt_k_n_m_ * 1e3;
    u_mm[static_cast<size_t>(i)] += weight_mm_[static_cast<size_t>(i)];
  }
}

}  // namespace feedloop::control
