// Fixed-step RK4 closed loop of the maneuvering controller and the DC-motor plant (simulation.hpp).
#include "maneuver/simulation.hpp"

#include <algorithm>  // std::max
#include <cmath>      // std::abs, std::hypot, std::ceil, std::isfinite
#include <string>

namespace feedloop::maneuver {

namespace {

struct LoopState {
  PlantState x;
  ManeuverState c;
};

struct LoopDerivative {
  PlantDerivative x;
  double dtheta;
  double domega_s;
};

struct Loop {
  const PiecewiseLinearPath& path;
  const SpeedAssignment& speed;
  const ManeuverController& ctl;
  const CartesianDcPlant& plant;
  bool fixed_segment;

  size_t segment_for(const LoopState& s, size_t n) const {
    return fixed_segment ? n : path.segment_at(s.c.theta);
  }
  LoopDerivative f(const LoopState& s, size_t n) const {
    const ManeuverOutput o = ctl.evaluate(path, speed, s.x, s.c, segment_for(s, n));
    return {plant.derivative(s.x, o.w_v), o.dtheta, o.domega_s};
  }
  static LoopState add(const LoopState& s, const LoopDerivative& d, double h) {
    return {{s.x.x1_m + h * d.x.dx1_m_s, s.x.x2_m_s + h * d.x.dx2_m_s2},
            {s.c.theta + h * d.dtheta, s.c.omega_s + h * d.domega_s}};
  }
  LoopState rk4(const LoopState& s, size_t n, double h) const {
    const LoopDerivative k1 = f(s, n);
    const LoopDerivative k2 = f(add(s, k1, 0.5 * h), n);
    const LoopDerivative k3 = f(add(s, k2, 0.5 * h), n);
    const LoopDerivative k4 = f(add(s, k3, h), n);
    LoopState r = s;
    r.x.x1_m += h / 6.0 * (k1.x.dx1_m_s + 2.0 * k2.x.dx1_m_s + 2.0 * k3.x.dx1_m_s + k4.x.dx1_m_s);
    r.x.x2_m_s += h / 6.0 * (k1.x.dx2_m_s2 + 2.0 * k2.x.dx2_m_s2 + 2.0 * k3.x.dx2_m_s2 + k4.x.dx2_m_s2);
    r.c.theta += h / 6.0 * (k1.dtheta + 2.0 * k2.dtheta + 2.0 * k3.dtheta + k4.dtheta);
    r.c.omega_s += h / 6.0 * (k1.domega_s + 2.0 * k2.domega_s + 2.0 * k3.domega_s + k4.domega_s);
    return r;
  }
};

// Eq. 70 on segment n: along-track s and cross-track e of z_1.
void track_errors(const PiecewiseLinearPath& path, size_t n, const Vec3& z1, double& along, double& cross) {
  const Vec3& t = path.dyd(n);
  const double txy = std::hypot(t.x(), t.y());
  if (txy < 1e-12 * t.norm()) {  // vertical segment: no heading phi
    along = z1.z() * (t.z() >= 0.0 ? 1.0 : -1.0);
    cross = std::hypot(z1.x(), z1.y());
    return;
  }
  const double c = t.x() / txy, s = t.y() / txy;  // cos phi, sin phi
  along = c * z1.x() + s * z1.y();
  cross = -s * z1.x() + c * z1.y();
}

Result<SimResult> run_sampled(const PiecewiseLinearPath& path, const SpeedAssignment& speed,
                              const ManeuverController& controller, SampledPlant& plant,
                              const SimOptions& opt) {
  ManeuverServo servo(path, speed, controller, opt.split_at_waypoints);
  const double period = opt.control_period_s;
  const auto max_periods = static_cast<size_t>(opt.max_time_s / period) + 1;
  SimResult r;
  r.segment_entry_s.assign(path.segments() + 1, -1.0);
  r.segment_entry_s[1] = 0.0;
  if (opt.record_every > 0) r.samples.reserve(max_periods / opt.record_every / 8 + 16);
  double t = 0.0;
  size_t limited = 0, periods = 0;
  for (size_t k = 0; k < max_periods; ++k) {
    const size_t n = servo.segment();
    const double theta = servo.state().theta;
    const Vec3 w = servo.update(plant.measure(), period);
    const ManeuverOutput& o = servo.last();
    // The true nozzle against y_d(theta) (for the controller's own model, o.z1_m).
    const Vec3 nozzle = plant.nozzle_m();
    const Vec3 z1 = nozzle - path.yd(theta, n);
    double along = 0.0, cross = 0.0;
    track_errors(path, n, z1, along, cross);
    r.max_cross_m = std::max(r.max_cross_m, std::abs(cross));
    r.max_along_m = std::max(r.max_along_m, std::abs(along));
    r.iae_cross_m_s += std::abs(cross) * period;
    if (opt.record_every > 0 && k % opt.record_every == 0)
      r.samples.push_back({t, nozzle, theta, n, along, cross, o.lyapunov,
                           plant.nozzle_velocity_m_s().norm(), o.speed.v_s * path.dyd(n).norm()});
    plant.advance(w, period);
    ++periods;
    if (plant.limited()) ++limited;
    r.steps += static_cast<size_t>(std::max(1.0, std::ceil(period / opt.dt_s - 1e-9)));
    t += period;
    const size_t m = servo.segment();
    for (size_t j = opt.split_at_waypoints ? n + 1 : m; j <= m; ++j)
      if (r.segment_entry_s[j] < 0.0) r.segment_entry_s[j] = t;
    if (!std::isfinite(plant.nozzle_m().squaredNorm()) || z1.norm() > 0.1 + path.length_m())
      return Error{"simulation: the sampled loop diverged at t = " + std::to_string(t) +
                       " s (|z_1| = " + std::to_string(z1.norm()) + " m): the control period " +
                       std::to_string(period) + " s is too long for these gains (K_d T = " +
                       std::to_string(controller.gains().k_d * period) +
                       "; with Table II's gains 1.5 holds, 1.67 diverges)",
                   {}};
    if (servo.finished()) {
      r.finished = true;
      r.total_time_s = t;
      break;
    }
  }
  r.skipped_segments = servo.skipped_segments();
  r.limited_fraction =
      periods > 0 ? static_cast<double>(limited) / static_cast<double>(periods) : 0.0;
  return r;
}

}  // namespace

void NominalSampledPlant::advance(const Vec3& w_v, double period_s) {
  const int n = std::max(1, static_cast<int>(std::ceil(period_s / max_step_s_ - 1e-9)));
  const double h = period_s / n;
  for (int i = 0; i < n; ++i) plant_.step_rk4(x_, w_v, h);
}

Result<SimResult> simulate(const PiecewiseLinearPath& path, const SpeedAssignment& speed,
                           const ManeuverController& controller, const CartesianDcPlant& plant,
                           const SimOptions& opt) {
  if (!(opt.dt_s > 0.0) || !(opt.max_time_s > 0.0))
    return Error{"simulation: dt_s and max_time_s must be positive", {}};
  if (opt.control_period_s > 0.0) {
    NominalSampledPlant sampled(plant, opt.dt_s);
    PlantState x = opt.initial;
    if (opt.start_at_path) x.x1_m = path.point(0);
    sampled.set_state(x);
    return run_sampled(path, speed, controller, sampled, opt);
  }
  const Loop loop{path, speed, controller, plant, opt.split_at_waypoints};
  LoopState s{opt.initial, {path.theta(0), 0.0}};
  if (opt.start_at_path) s.x.x1_m = path.point(0);
  size_t n = 1;
  SimResult r;
  double t = 0.0;
  const double theta_end = path.theta_end();
  const size_t max_steps = static_cast<size_t>(opt.max_time_s / opt.dt_s) + 1;
  if (opt.record_every > 0) r.samples.reserve(max_steps / opt.record_every / 8 + 16);
  r.segment_entry_s.assign(path.segments() + 1, -1.0);
  r.segment_entry_s[1] = 0.0;
  auto enter = [&](size_t m, double at_s) {
    if (r.segment_entry_s[m] < 0.0) r.segment_entry_s[m] = at_s;
  };

  auto record = [&](double h, bool keep) {
    const ManeuverOutput o = controller.evaluate(path, speed, s.x, s.c, n);
    double along = 0.0, cross = 0.0;
    track_errors(path, n, o.z1_m, along, cross);
    r.max_cross_m = std::max(r.max_cross_m, std::abs(cross));
    r.max_along_m = std::max(r.max_along_m, std::abs(along));
    r.iae_cross_m_s += std::abs(cross) * h;
    if (keep)
      r.samples.push_back({t, s.x.x1_m, s.c.theta, n, along, cross, o.lyapunov, s.x.x2_m_s.norm(),
                           o.speed.v_s * path.dyd(n).norm()});
  };
  record(0.0, opt.record_every > 0);

  size_t step = 0;
  while (t < opt.max_time_s && step < max_steps) {
    double remaining = opt.dt_s;
    while (remaining > 0.0) {  // one step, split at waypoints when asked
      LoopState next = loop.rk4(s, n, remaining);
      double h = remaining;
      if (opt.split_at_waypoints && n < path.segments() && next.c.theta > path.theta(n)) {
        const double frac = (path.theta(n) - s.c.theta) / (next.c.theta - s.c.theta);
        h = remaining * std::clamp(frac, 0.0, 1.0);
        next = h > 0.0 ? loop.rk4(s, n, h) : s;
        next.c.theta = path.theta(n);  // land exactly on the waypoint
        s = next;
        ++n;
        enter(n, t + h);
      } else {
        s = next;
        const size_t m = path.segment_at(s.c.theta);
        if (!opt.split_at_waypoints && m > n + 1) r.skipped_segments += m - n - 1;
        n = opt.split_at_waypoints ? (s.c.theta < path.theta(n - 1) ? m : n) : m;
        enter(n, t + h);
      }
      remaining -= h;
      t += h;
      ++r.steps;
      record(h, false);
      if (s.c.theta >= theta_end) break;
    }
    ++step;
    if (opt.record_every > 0 && step % opt.record_every == 0) record(0.0, true);
    if (s.c.theta >= theta_end) {
      r.finished = true;
      r.total_time_s = t;
      break;
    }
  }
  if (opt.record_every > 0 && step % opt.record_every != 0) record(0.0, true);
  return r;
}

}  // namespace feedloop::maneuver

namespace feedloop::maneuver {

Result<SimResult> simulate_sampled(const PiecewiseLinearPath& path, const SpeedAssignment& speed,
                                   const ManeuverController& controller, SampledPlant& plant,
                                   const SimOptions& opt) {
  if (!(opt.control_period_s > 0.0) || !(opt.dt_s > 0.0) || !(opt.max_time_s > 0.0))
    return Error{"simulation: control_period_s, dt_s and max_time_s must be positive", {}};
  plant.reset(path.point(0));
  return run_sampled(path, speed, controller, plant, opt);
}

}  // namespace feedloop::maneuver
