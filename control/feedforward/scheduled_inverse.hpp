// The real-time half of the preview inverse (preview_design.hpp, law (2)) for an LPV model:
// a table of designs precomputed at grid points of the scheduling variable (carriage position on
// a gantry axis, nozzle position on a delta) and, every period, their blend at the current point
// (linear/trilinear interpolation weights from the caller) applied to the feedforward's own copy
// of the model:
//   v_k = -K(p) x_k + sum_i F_i(p) r_{k+i},   x_{k+1} = A(p) x_k + B(p) v_k
// run in deviation form (x relative to the model's rest state at r_k, see step()), so that the
// re-scheduled linear model only ever sees reference differences, never absolute positions.
// The blended model and gains are a convex combination of the neighbours' (same state
// coordinates at every point, so the blend is meaningful).
//
// Owner: one thread. configure() allocates; reset(), push(), schedule(), step() do not
// allocate, lock or throw (RT-safe).
#pragma once

#include <vector>

#include "control/feedforward/preview_design.hpp"
#include "core/result.hpp"

namespace feedloop::control {

class ScheduledPreviewInverse {
 public:
  // All designs must have the same dimensions and preview.
  Status configure(const std::vector<PreviewInverse>& table, CommandHold hold);

  int inputs() const { return m_; }
  int states() const { return n_; }
  int preview_samples() const { return P_; }
  int points() const { return points_; }

  // RT-safe. Selects the blend sum_c w[c] design[idx[c]] (count <= 8, weights summing to 1).
  void schedule(const int* idx, const double* w, int count);
  // RT-safe. At rest at reference r (m values): r held for every past and previewed sample.
  void reset(const double* r);
  // RT-safe. Appends r_{k+P} to the preview buffer; reference(0) is then r_k.
  void push(const double* r_ahead);
  // r_{k+i} (i in 0..P) of input j, after push().
  double reference(int i, int j) const {
    return refs_[static_cast<size_t>(((head_ + i) % (P_ + 1)) * m_ + j)];
  }
  // RT-safe. After push() and schedule(): u_k (m values) and the internal model advanced.
  void step(double* u);

 private:
  int n_ = 0, m_ = 0, P_ = 0, points_ = 0;
  CommandHold hold_ = CommandHold::linear;
  size_t stride_ = 0;                 // doubles per packed design
  size_t off_b_ = 0, off_k_ = 0, off_f_ = 0, off_rest_ = 0;
  std::vector<double> table_;         // points_ * stride_
  std::vector<double> cur_;           // the blended design
  std::vector<double> x_, x_next_, v_;
  std::vector<double> refs_;          // ring of (P+1) references, m each
  int head_ = 0;                      // index of r_k in the ring
};

}  // namespace feedloop::control
