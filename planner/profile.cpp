// Closed-form trapezoid and jerk-limited S-curve pieces (see profile.hpp).
#include "planner/profile.hpp"

#include "planner/scurve.hpp"

#include <algorithm>  // std::max, std::min, std::clamp
#include <cmath>      // sqrt

namespace feedloop::planner {

namespace {

void push_piece(PlannedMove& m, double duration, double a0, double jerk) {
  if (duration <= 0.0) return;
  ProfilePiece p;
  if (m.piece_count > 0) {
    const ProfilePiece& q = m.pieces[m.piece_count - 1];
    p.t_s = q.t_s + q.duration_s;
    p.s0_mm = q.distance_mm(q.duration_s);
    p.v0_mm_s = q.velocity_mm_s(q.duration_s);
  } else {
    p.v0_mm_s = m.v_entry_mm_s;
  }
  p.duration_s = duration;
  p.a0_mm_s2 = a0;
  p.jerk_mm_s3 = jerk;
  m.pieces[m.piece_count++] = p;
}

// One speed-change phase of duration T and signed change dv.
void push_phase(PlannedMove& m, double T, double dv, ProfileShape shape, double jerk, double peak_accel) {
  if (T <= 0.0) return;
  const double sign = dv >= 0.0 ? 1.0 : -1.0;
  const double adv = std::abs(dv);
  if (shape == ProfileShape::trapezoid || adv <= 0.0) {
    push_piece(m, T, dv / T, 0.0);
    return;
  }
  double A;  // peak |acceleration|
  double disc = jerk * jerk * T * T - 4.0 * jerk * adv;
  if (disc < 0.0 && disc > -1e-9 * jerk * jerk * T * T) disc = 0.0;  // T at its minimum, rounded
  if (disc >= 0.0) {
    A = 0.5 * (jerk * T - std::sqrt(disc));
  } else {
    A = 2.0 * adv / T;  // triangular acceleration
    m.jerk_bounded = false;
  }
  A = std::clamp(A, adv / T, std::max(adv / T, std::min(2.0 * adv / T, peak_accel)));
  const double tj = std::max(0.0, T - adv / A);
  const double tc = std::max(0.0, T - 2.0 * tj);
  if (tj <= 0.0) {
    push_piece(m, T, dv / T, 0.0);
    if (adv > 0.0) m.jerk_bounded = false;
    return;
  }
  const double j = A / tj;
  if (j > jerk * (1.0 + 1e-9)) m.jerk_bounded = false;
  push_piece(m, tj, 0.0, sign * j);
  push_piece(m, tc, sign * A, 0.0);
  push_piece(m, tj, sign * A, -sign * j);
}

}  // namespace

void build_profile(PlannedMove& m, ProfileShape shape, double max_jerk_mm_s3, double peak_accel_mm_s2) {
  const double a = m.accel_mm_s2;
  const double v0 = m.v_entry_mm_s, vc = m.v_cruise_mm_s, v1 = m.v_exit_mm_s;
  m.accel_t_s = (vc - v0) / a;
  m.decel_t_s = (vc - v1) / a;
  const double accel_d = 0.5 * (v0 + vc) * m.accel_t_s;
  const double decel_d = 0.5 * (v1 + vc) * m.decel_t_s;
  double cruise_d = std::max(0.0, m.length_mm - accel_d - decel_d);
  m.jerk_bounded = true;
  m.piece_count = 0;
  if (shape == ProfileShape::scurve) {
    // Jerk-limited phases of minimum duration; the lookahead chose speeds that fit (scurve.hpp).
    m.accel_t_s = scurve_min_time(vc - v0, peak_accel_mm_s2, max_jerk_mm_s3);
    m.decel_t_s = scurve_min_time(vc - v1, peak_accel_mm_s2, max_jerk_mm_s3);
    cruise_d = std::max(0.0, m.length_mm - 0.5 * (v0 + vc) * m.accel_t_s - 0.5 * (v1 + vc) * m.decel_t_s);
  }
  m.cruise_t_s = vc > 0.0 ? cruise_d / vc : 0.0;
  m.duration_s = m.accel_t_s + m.cruise_t_s + m.decel_t_s;
  push_phase(m, m.accel_t_s, vc - v0, shape, max_jerk_mm_s3, peak_accel_mm_s2);
  push_piece(m, m.cruise_t_s, 0.0, 0.0);
  push_phase(m, m.decel_t_s, v1 - vc, shape, max_jerk_mm_s3, peak_accel_mm_s2);
}

PathState path_state(const PlannedMove& m, double t_s) {
  PathState st;
  if (m.piece_count == 0) return st;
  int k = 0;
  while (k + 1 < m.piece_count && t_s >= m.pieces[k + 1].t_s) ++k;
  const ProfilePiece& p = m.pieces[k];
  const double tau = std::clamp(t_s - p.t_s, 0.0, p.duration_s);
  st.s_mm = p.distance_mm(tau);
  st.v_mm_s = p.velocity_mm_s(tau);
  st.a_mm_s2 = p.accel_mm_s2(tau);
  st.jerk_mm_s3 = p.jerk_mm_s3;
  return st;
}

}  // namespace feedloop::planner
