// Real-time blending and stepping of the preview inverse (see scheduled_inverse.hpp).
#include "control/feedforward/scheduled_inverse.hpp"

#include <algorithm>  // std::fill, std::copy

namespace feedloop::control {

namespace {
// Column-major copy of an Eigen matrix into a packed array.
void pack(const Eigen::MatrixXd& a, double* dst) {
  for (Eigen::Index c = 0; c < a.cols(); ++c)
    for (Eigen::Index r = 0; r < a.rows(); ++r) *dst++ = a(r, c);
}
}  // namespace

Status ScheduledPreviewInverse::configure(const std::vector<PreviewInverse>& table, CommandHold hold) {
  if (table.empty()) return Error{"scheduled inverse: no design", {}};
  const PreviewInverse& d0 = table.front();
  n_ = static_cast<int>(d0.A.rows());
  m_ = static_cast<int>(d0.B.cols());
  P_ = static_cast<int>(d0.F.size()) - 1;
  if (n_ < 1 || m_ < 1 || P_ < 1) return Error{"scheduled inverse: empty design", {}};
  const size_t n = static_cast<size_t>(n_), m = static_cast<size_t>(m_), P = static_cast<size_t>(P_);
  off_b_ = n * n;
  off_k_ = off_b_ + n * m;
  off_f_ = off_k_ + m * n;
  off_rest_ = off_f_ + (P + 1) * m * m;
  stride_ = off_rest_ + n * m;
  points_ = static_cast<int>(table.size());
  table_.assign(table.size() * stride_, 0.0);
  for (size_t i = 0; i < table.size(); ++i) {
    const PreviewInverse& d = table[i];
    if (d.A.rows() != n_ || d.B.cols() != m_ || d.K.rows() != m_ || d.F.size() != P + 1 ||
        d.rest_state.rows() != n_)
      return Error{"scheduled inverse: designs of different sizes", {}};
    double* base = table_.data() + i * stride_;
    pack(d.A, base);
    pack(d.B, base + off_b_);
    pack(d.K, base + off_k_);
    for (size_t f = 0; f <= P; ++f) pack(d.F[f], base + off_f_ + f * m * m);
    pack(d.rest_state, base + off_rest_);
  }
  hold_ = hold;
  cur_.assign(table_.begin(), table_.begin() + static_cast<std::ptrdiff_t>(stride_));
  x_.assign(n, 0.0);
  x_next_.assign(n, 0.0);
  v_.assign(m, 0.0);
  refs_.assign((P + 1) * m, 0.0);
  head_ = 0;
  return {};
}

void ScheduledPreviewInverse::schedule(const int* idx, const double* w, int count) {
  double* cur = cur_.data();
  const double* t0 = table_.data() + static_cast<size_t>(idx[0]) * stride_;
  const double w0 = w[0];
  for (size_t i = 0; i < stride_; ++i) cur[i] = w0 * t0[i];
  for (int c = 1; c < count; ++c) {
    if (w[c] == 0.0) continue;
    const double* t = table_.data() + static_cast<size_t>(idx[c]) * stride_;
    const double wc = w[c];
    for (size_t i = 0; i < stride_; ++i) cur[i] += wc * t[i];
  }
}

void ScheduledPreviewInverse::reset(const double* r) {
  std::fill(x_.begin(), x_.end(), 0.0);  // at rest: no deviation from the rest state
  for (int k = 0; k <= P_; ++k) std::copy(r, r + m_, refs_.begin() + k * m_);
  head_ = 0;
}

void ScheduledPreviewInverse::push(const double* r_ahead) {
  // The slot of the oldest reference (r_{k-1}) becomes r_{k+P}.
  std::copy(r_ahead, r_ahead + m_, refs_.begin() + head_ * m_);
  head_ = (head_ + 1) % (P_ + 1);
}

void ScheduledPreviewInverse::step(double* u) {
  // Deviation form (docs/feedforward.md): x~ = x - X_rest r_k, the model's state relative to its
  // rest state at the current reference, so that only reference differences enter and the
  // re-scheduled model never sees an absolute position (an LPV model is linear about its
  // operating point; X_rest depends on it, e.g. the delta effector's X2 = Jbar q):
  //   v_k - r_k = -K x~_k + sum_{i>=1} F_i (r_{k+i} - r_k)        (law (2); sum F_i - K X_rest = I)
  //   x~_{k+1} = A x~_k + B (v_k - r_k) - X_rest (r_{k+1} - r_k)   ((I - A) X_rest = B)
  const int n = n_, m = m_;
  const double* A = cur_.data();
  const double* B = A + off_b_;
  const double* K = A + off_k_;
  const double* F = A + off_f_;
  const double* rest = A + off_rest_;
  const double* r0 = refs_.data() + head_ * m;
  for (int r = 0; r < m; ++r) {
    double s = 0.0;
    for (int c = 0; c < n; ++c) s -= K[c * m + r] * x_[static_cast<size_t>(c)];
    v_[static_cast<size_t>(r)] = s;
  }
  for (int i = 1; i <= P_; ++i) {
    const double* fi = F + i * m * m;
    const double* ri = refs_.data() + ((head_ + i) % (P_ + 1)) * m;
    for (int c = 0; c < m; ++c) {
      const double dc = ri[c] - r0[c];
      for (int r = 0; r < m; ++r) v_[static_cast<size_t>(r)] += fi[c * m + r] * dc;
    }
  }
  // u_k: the input itself (zero-order hold) or the stored command of the linear hold (last m states).
  for (int j = 0; j < m; ++j)
    u[j] = r0[j] + (hold_ == CommandHold::zero_order ? v_[static_cast<size_t>(j)] : x_[static_cast<size_t>(n - m + j)]);
  const double* r1 = refs_.data() + ((head_ + 1) % (P_ + 1)) * m;
  for (int r = 0; r < n; ++r) {
    double s = 0.0;
    for (int c = 0; c < n; ++c) s += A[c * n + r] * x_[static_cast<size_t>(c)];
    for (int c = 0; c < m; ++c) s += B[c * n + r] * v_[static_cast<size_t>(c)] - rest[c * n + r] * (r1[c] - r0[c]);
    x_next_[static_cast<size_t>(r)] = s;
  }
  x_.swap(x_next_);
}

}  // namespace feedloop::control
