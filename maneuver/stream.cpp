// Streaming path window and servo (see stream.hpp).
#include "maneuver/stream.hpp"

#include <algorithm>  // std::clamp
#include <cmath>      // std::hypot

#include "planner/junction.hpp"

namespace feedloop::maneuver {

PathWindow::PathWindow(size_t capacity, Parameterization param) : param_(param), pts_(std::max<size_t>(capacity, 2)) {}

void PathWindow::clear() {
  first_ = last_ + 1;  // numbering continues
}

bool PathWindow::push(const StreamWaypoint& w, double min_segment_m) {
  if (!empty()) {
    Slot& prev = pts_[last_ % pts_.size()];
    const Vec3 delta = w.p_m - prev.w.p_m;  // Delta_n, Eq. 65
    const double len = delta.norm();
    if (!(len >= min_segment_m)) {  // no direction: the newest waypoint takes the new data
      prev.w.k = w.k;
      prev.w.e_mm = w.e_mm;
      prev.w.line = w.line;
      return true;
    }
    if (full()) return false;
    if (w.k_prev >= 0.0) prev.w.k = w.k_prev;
    Slot& slot = pts_[(last_ + 1) % pts_.size()];
    const double dtheta = param_ == Parameterization::unit ? 1.0 : len;  // Eq. 24 or arc length
    slot.w = w;
    slot.theta = prev.theta + dtheta;
    slot.s_m = prev.s_m + len;
    slot.dyd = delta / dtheta;  // Eq. 22
    ++last_;
    return true;
  }
  Slot& slot = pts_[first_ % pts_.size()];
  slot.w = w;
  slot.theta = 0.0;
  slot.s_m = 0.0;
  slot.dyd = Vec3::Zero();
  last_ = first_;
  return true;
}

void PathWindow::release_before(uint64_t n) {
  if (empty()) return;
  first_ = std::clamp(n, first_, last_);
}

SpeedValue stream_speed_at(const PathWindow& w, const StreamSpeed& speed, double theta, uint64_t n) {
  const SpeedParams& p = speed.params;
  const double dtheta_seg = w.theta(n) - w.theta(n - 1);
  const double len = w.s_m(n) - w.s_m(n - 1);
  const double speed_scale = p.m_s_m_s * dtheta_seg / len;  // m_s / ||dy_d/dtheta||
  const double k_prev = w.k_effective(n - 1), k_next = w.k_effective(n);
  double factor = 1.0, df_dtheta = 0.0;
  const double u = (theta - w.theta(n - 1)) / dtheta_seg;
  switch (speed.profile) {
    case SpeedProfile::constant:  // Eq. 63, except into and out of a stop
      if (k_prev > 0.0 || k_next > 0.0) {
        double df_du = 0.0;
        factor = paper_speed_factor(u, k_prev, k_next, p.sharp, df_du);
        df_dtheta = df_du / dtheta_seg;
      }
      break;
    case SpeedProfile::every_transition:
    case SpeedProfile::sharp_corner: {  // Eq. 67
      double df_du = 0.0;
      factor = paper_speed_factor(u, k_prev, k_next, p.sharp, df_du);
      df_dtheta = df_du / dtheta_seg;
      break;
    }
    case SpeedProfile::sharp_corner_arc: {
      planner::SharpCornerParams sig = p.sharp;
      sig.a1 = p.a1_m;
      sig.a2 = p.a2_m;
      const double h_reach = planner::sharp_corner_h(p.reach_m, sig);
      const double s = w.arc_length(theta, n);
      double df_ds = 0.0;
      auto consider = [&](uint64_t j) {
        const double d = std::abs(s - w.s_m(j));
        const double k = w.k_effective(j);
        if (d >= p.reach_m || k == 0.0) return;
        double dg_dd = 0.0;
        const double g = arc_corner_factor(d, k, sig, h_reach, dg_dd);
        if (g < factor) {
          factor = g;
          df_ds = (s >= w.s_m(j) ? 1.0 : -1.0) * dg_dd;
        }
      };
      for (uint64_t j = n - 1;; --j) {  // corners behind, while within reach
        if (s - w.s_m(j) >= p.reach_m) break;
        consider(j);
        if (j == w.first()) break;
      }
      for (uint64_t j = n; j <= w.last(); ++j) {  // corners ahead
        if (w.s_m(j) - s >= p.reach_m) break;
        consider(j);
      }
      df_dtheta = df_ds * len / dtheta_seg;
      break;
    }
  }
  SpeedValue v;
  v.factor = factor;
  v.v_s = speed_scale * factor;
  v.dv_s_dtheta = speed_scale * df_dtheta;
  return v;
}

TrackError track_error(const Vec3& z1, const Vec3& dyd) {
  TrackError e;
  const double txy = std::hypot(dyd.x(), dyd.y());
  if (!(txy > 1e-12)) {  // a segment without XY extent (a layer change)
    e.cross_m = std::hypot(z1.x(), z1.y());
    return e;
  }
  const double cx = dyd.x() / txy, sy = dyd.y() / txy;  // cos phi, sin phi
  e.along_m = z1.x() * cx + z1.y() * sy;                 // Eq. 70
  e.cross_m = -z1.x() * sy + z1.y() * cx;
  return e;
}

StreamServo::StreamServo(PathWindow& window, const StreamSpeed& speed, const ManeuverController& ctl)
    : window_(window), speed_(speed), ctl_(ctl) {}

void StreamServo::start_at(uint64_t n) {
  n_ = n;
  hold_ = true;
  c_ = {window_.empty() ? 0.0 : window_.theta(n), 0.0};
  last_ = {};
  err_ = {};
  update_position();
}

uint64_t StreamServo::oldest_needed() const {
  uint64_t j = hold_ ? n_ : n_ - 1;  // the start of the segment being followed
  const double reach = speed_.profile == SpeedProfile::sharp_corner_arc ? speed_.params.reach_m : 0.0;
  while (j > window_.first() && s_m_ - window_.s_m(j) < reach) --j;
  return j > window_.first() ? j - 1 : j;  // one more behind: theta may step back a segment
}

ManeuverOutput StreamServo::eval(const PlantState& x, const ManeuverState& c, uint64_t n) const {
  return ctl_.evaluate_at(window_.yd(c.theta, n), window_.dyd(n), stream_speed_at(window_, speed_, c.theta, n), x, c);
}

ManeuverState StreamServo::rk4(const PlantState& x, const ManeuverState& c, uint64_t n, double h) const {
  auto f = [&](const ManeuverState& s) {
    const ManeuverOutput o = eval(x, s, n);
    return ManeuverState{o.dtheta, o.domega_s};
  };
  auto add = [](const ManeuverState& s, const ManeuverState& d, double k) {
    return ManeuverState{s.theta + k * d.theta, s.omega_s + k * d.omega_s};
  };
  const ManeuverState k1 = f(c), k2 = f(add(c, k1, 0.5 * h)), k3 = f(add(c, k2, 0.5 * h)), k4 = f(add(c, k3, h));
  return {c.theta + h / 6.0 * (k1.theta + 2.0 * k2.theta + 2.0 * k3.theta + k4.theta),
          c.omega_s + h / 6.0 * (k1.omega_s + 2.0 * k2.omega_s + 2.0 * k3.omega_s + k4.omega_s)};
}

void StreamServo::update_position() {
  if (window_.empty()) return;
  if (hold_) {
    s_m_ = window_.s_m(n_);
    e_mm_ = window_.waypoint(n_).e_mm;
    return;
  }
  s_m_ = window_.arc_length(c_.theta, n_);
  const double u = std::clamp((c_.theta - window_.theta(n_ - 1)) / (window_.theta(n_) - window_.theta(n_ - 1)), 0.0, 1.0);
  e_mm_ = window_.waypoint(n_ - 1).e_mm + u * (window_.waypoint(n_).e_mm - window_.waypoint(n_ - 1).e_mm);
}

Vec3 StreamServo::update(const PlantState& x, double period_s) {
  if (window_.empty()) return Vec3::Zero();
  if (hold_ && window_.last() > n_) {  // a segment ahead: follow it from its start
    window_.set_k(n_, 1.0);             // it stood still here: start as from a stop
    ++n_;
    hold_ = false;
    c_ = {window_.theta(n_ - 1), 0.0};
    ++entered_;
  }
  if (hold_) {  // regulate z_1 to 0 at the held waypoint (v_s = 0)
    c_ = {window_.theta(n_), 0.0};
    last_ = ctl_.evaluate_at(window_.point(n_), Vec3::Zero(), SpeedValue{}, x, c_);
    err_ = track_error(last_.z1_m, Vec3::Zero());
    update_position();
    return last_.w_v;
  }
  last_ = eval(x, c_, n_);  // Eq. 45 at the sample: held for the period
  err_ = track_error(last_.z1_m, window_.dyd(n_));
  double remaining = period_s;
  while (remaining > 0.0) {
    ManeuverState next = rk4(x, c_, n_, remaining);
    double h = remaining;
    if (next.theta > window_.theta(n_)) {  // crosses p_n: land on it, go on with the next segment
      const double frac = (window_.theta(n_) - c_.theta) / (next.theta - c_.theta);
      h = remaining * std::clamp(frac, 0.0, 1.0);
      next = h > 0.0 ? rk4(x, c_, n_, h) : c_;
      next.theta = window_.theta(n_);
      c_ = next;
      if (n_ == window_.last()) {  // the end of the known path: hold there
        hold_ = true;
        c_.omega_s = 0.0;
        break;
      }
      ++n_;
      ++entered_;
    } else {
      c_ = next;
      if (c_.theta < window_.theta(n_ - 1)) {  // theta stepped back over p_{n-1}
        if (n_ - 1 > window_.first()) --n_;
        else c_.theta = window_.theta(n_ - 1);
      }
    }
    remaining -= h;
  }
  update_position();
  return last_.w_v;
}

}  // namespace feedloop::maneuver
