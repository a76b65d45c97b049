// Joint segments from planned moves (see joint_output.hpp).
#include "planner/joint_output.hpp"

#include <algorithm>  // std::min
#include <cmath>      // floor

namespace feedloop::planner {

namespace {
constexpr double kMinPiece_s = 1e-12;

Vec3 xyz_at(const PlannedMove& m, double s) {
  return {m.start_mm[0] + m.unit[0] * s, m.start_mm[1] + m.unit[1] * s, m.start_mm[2] + m.unit[2] * s};
}

void emit_extruder(const PlannedMove& m, const ProfilePiece& p, JointSink& sink) {
  const double u = m.unit[kE];
  JointSegment seg;
  seg.t0_s = m.start_time_s + p.t_s;
  seg.duration_s = p.duration_s;
  seg.c0_mm = m.start_mm[kE] + u * p.s0_mm;
  seg.c1_mm_s = u * p.v0_mm_s;
  seg.c2_mm_s2 = 0.5 * u * p.a0_mm_s2;
  seg.c3_mm_s3 = u * p.jerk_mm_s3 / 6.0;
  sink.on_joint_segment(3, seg);
}
}  // namespace

JointEmitter::JointEmitter(const Kinematics& kinematics, double servo_period_s)
    : kin_(kinematics), period_s_(servo_period_s) {}

void JointEmitter::emit(const PlannedMove& m, JointSink& sink) const {
  if (kin_.is_linear() || !m.kinematic) {
    emit_linear(m, sink);
  } else {
    emit_hermite(m, sink);
  }
}

void JointEmitter::emit_linear(const PlannedMove& m, JointSink& sink) const {
  const std::array<Vec3, 3> M = kin_.linear_map();
  const Joints q0 = kin_.inverse({m.start_mm[0], m.start_mm[1], m.start_mm[2]});
  Joints mu{};  // M u: joint mm per mm of path
  if (kin_.is_linear()) {
    for (int j = 0; j < 3; ++j) mu[j] = M[j][0] * m.unit[0] + M[j][1] * m.unit[1] + M[j][2] * m.unit[2];
  }  // a non-kinematic (E-only) move on a delta: joints stand still, mu = 0
  for (int k = 0; k < m.piece_count; ++k) {
    const ProfilePiece& p = m.pieces[k];
    if (p.duration_s < kMinPiece_s) continue;
    for (int j = 0; j < 3; ++j) {
      JointSegment seg;
      seg.t0_s = m.start_time_s + p.t_s;
      seg.duration_s = p.duration_s;
      seg.c0_mm = q0[j] + mu[j] * p.s0_mm;
      seg.c1_mm_s = mu[j] * p.v0_mm_s;
      seg.c2_mm_s2 = 0.5 * mu[j] * p.a0_mm_s2;
      seg.c3_mm_s3 = mu[j] * p.jerk_mm_s3 / 6.0;
      sink.on_joint_segment(j, seg);
    }
    emit_extruder(m, p, sink);
  }
}

void JointEmitter::emit_hermite(const PlannedMove& m, JointSink& sink) const {
  for (int k = 0; k < m.piece_count; ++k) {
    const ProfilePiece& p = m.pieces[k];
    if (p.duration_s < kMinPiece_s) continue;
    emit_extruder(m, p, sink);
    const double t_begin = m.start_time_s + p.t_s;  // absolute
    const double t_end = t_begin + p.duration_s;
    double ta = t_begin;
    Vec3 xa = xyz_at(m, p.s0_mm);
    Joints qa, va;
    kin_.inverse_with_velocity(xa, {m.unit[0] * p.v0_mm_s, m.unit[1] * p.v0_mm_s, m.unit[2] * p.v0_mm_s}, qa, va);
    while (ta < t_end - kMinPiece_s) {
      // next grid point k * period strictly after ta (absolute servo grid), or the piece end
      double tb = (std::floor(ta / period_s_ + 1e-9) + 1.0) * period_s_;
      if (tb > t_end - kMinPiece_s) tb = t_end;
      const double tau = tb - p.t_s - m.start_time_s;
      const double s = p.distance_mm(tau), v = p.velocity_mm_s(tau);
      const Vec3 xb = xyz_at(m, s);
      Joints qb, vb;
      kin_.inverse_with_velocity(xb, {m.unit[0] * v, m.unit[1] * v, m.unit[2] * v}, qb, vb);
      const double h = tb - ta;
      for (int j = 0; j < 3; ++j) {
        const double slope = (qb[j] - qa[j]) / h;
        JointSegment seg;
        seg.t0_s = ta;
        seg.duration_s = h;
        seg.c0_mm = qa[j];
        seg.c1_mm_s = va[j];
        seg.c2_mm_s2 = (3.0 * slope - 2.0 * va[j] - vb[j]) / h;
        seg.c3_mm_s3 = (va[j] + vb[j] - 2.0 * slope) / (h * h);
        sink.on_joint_segment(j, seg);
      }
      ta = tb;
      qa = qb;
      va = vb;
    }
  }
}

}  // namespace feedloop::planner
