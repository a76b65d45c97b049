#include "engine/maneuver_executor.hpp"

#include <algorithm>  // std::max, std::clamp
#include <cmath>      // std::ceil, std::abs
#include <cstdio>     // std::snprintf
#include <mutex>
#include <thread>     // sleep_for

#include "engine/config_mapping.hpp"
#include "engine/executor_factory.hpp"
#include "gcode/parser.hpp"
#include "planner/junction.hpp"

namespace feedloop::engine {
namespace {

using maneuver::StreamWaypoint;
using maneuver::Vec3;

constexpr double kMinSegmentM = 1e-9;

maneuver::CartesianDcParams plant_params(const config::CartesianDcConfig& c) {
  maneuver::CartesianDcParams p;  // Table I, g = 9.81
  p.m_n_kg = c.m_n_kg;
  p.m_x_kg = c.m_x_kg;
  p.m_ps_kg = c.m_ps_kg;
  p.j_m_kg_m2 = c.j_m_kg_m2;
  p.b_nm_s_rad = c.b_nm_s;
  p.r_a_ohm = c.r_a_ohm;
  p.k_m_nm_a = c.k_m_nm_per_a;
  p.r_m = c.pulley_radius_mm * 1e-3;
  return p;
}

maneuver::ManeuverGains gains(const config::ManeuverControlConfig& m) {
  maneuver::ManeuverGains g;  // Table II by default
  g.k_p = m.k_p_per_s;
  g.k_d = m.k_d_per_s;
  g.q1 = m.q1;
  g.q2 = m.q2;
  g.lambda = m.lambda_per_s;
  g.mu = m.mu;
  return g;
}

maneuver::StreamSpeed stream_speed(const config::MachineConfig& cfg) {
  const config::ManeuverControlConfig& m = cfg.control.maneuver;
  maneuver::StreamSpeed s;
  switch (m.speed_assignment) {
    case config::ManeuverSpeed::constant: s.profile = maneuver::SpeedProfile::constant; break;
    case config::ManeuverSpeed::every_transition: s.profile = maneuver::SpeedProfile::every_transition; break;
    case config::ManeuverSpeed::sharp_corner: s.profile = maneuver::SpeedProfile::sharp_corner; break;
    case config::ManeuverSpeed::sharp_corner_arc: s.profile = maneuver::SpeedProfile::sharp_corner_arc; break;
  }
  s.params.m_s_m_s = m.path_speed_mm_s * 1e-3;
  s.params.sharp.alpha_a_deg = cfg.planner.sharp_corner.alpha_a_deg;  // Eq. 64-68, Table II
  s.params.sharp.alpha_b_deg = cfg.planner.sharp_corner.alpha_b_deg;
  s.params.sharp.a1 = cfg.planner.sharp_corner.a1;
  s.params.sharp.a2 = cfg.planner.sharp_corner.a2;
  s.params.a1_m = m.arc_a1_mm * 1e-3;
  s.params.a2_m = m.arc_a2_mm * 1e-3;
  s.params.reach_m = m.arc_reach_mm * 1e-3;
  return s;
}

Vec3 xyz_m(const planner::Vec4& p_mm) { return Vec3(p_mm[0], p_mm[1], p_mm[2]) * 1e-3; }

void store_max(std::atomic<double>& a, double v) {
  if (v > a.load(std::memory_order_relaxed)) a.store(v, std::memory_order_relaxed);
}

}  // namespace

Result<std::unique_ptr<ManeuverExecutor>> ManeuverExecutor::create(const config::MachineConfig& cfg,
                                                                    const ManeuverExecutorOptions& options) {
  if (cfg.drive != config::Drive::dc_servo || cfg.control.mode != config::ControlMode::maneuver)
    return Error{"the maneuvering executor needs drive: dc_servo and control.mode: maneuver"};
  const planner::PlannerConfig pcfg = planner_config(cfg);
  if (Status s = pcfg.validate(); !s) return s.error();
  return std::unique_ptr<ManeuverExecutor>(new ManeuverExecutor(cfg, pcfg, options));
}

ManeuverExecutor::ManeuverExecutor(const config::MachineConfig& cfg, const planner::PlannerConfig& pcfg,
                                   const ManeuverExecutorOptions& options)
    : options_(options),
      period_s_(1.0 / cfg.servo.rate_hz),
      max_following_error_m_(cfg.control.max_following_error_mm * 1e-3),
      pcfg_(pcfg),
      kin_(planner::make_kinematics(pcfg_)),
      planner_(pcfg_, *this),
      plant_(plant_params(cfg.model.cartesian_dc)),
      ctl_(plant_, gains(cfg.control.maneuver)),
      speed_(stream_speed(cfg)),
      queue_(options.queue_capacity),
      window_(options.window_capacity,
              cfg.control.maneuver.parameterization == config::ManeuverParameterization::unit
                  ? maneuver::Parameterization::unit
                  : maneuver::Parameterization::arc_length),
      servo_(window_, speed_, ctl_) {
  interp_ = std::make_unique<planner::Interpreter>(pcfg_, *kin_, planner_);
  // Power-on: the plant rests where the interpreter starts, and the servo holds it there.
  const planner::Vec4& p0 = interp_->state().machine_mm;
  last_ = StreamWaypoint{xyz_m(p0), 1.0, p0[3], 0};
  window_.push(last_);
  servo_.start_at(window_.first());
  x_.x1_m = last_.p_m;
  for (int i = 0; i < 3; ++i) telemetry_.pos_mm[i].store(p0[static_cast<size_t>(i)]);
}

// ---- planner thread ------------------------------------------------------------------------------

Status ManeuverExecutor::execute(const gcode::Command& cmd, const std::atomic<bool>& cancel) {
  cancel_ = &cancel;
  wait_done_ = false;
  last_command_ = std::chrono::steady_clock::now();
  const bool motion = cmd.letter == 'G' && cmd.code >= 0 && cmd.code <= 3;
  if (motion && telemetry_.faulted.load())  // rejected: nothing changes
    return Error{"motion stopped: tracking error beyond control.max_following_error_mm"};
  if (motion) wait_for_room(cancel);
  Status st = interp_->execute(cmd);
  planner_queued_.store(planner_.queued());
  release();
  if (st && wait_done_) wait_motion_done(cancel);  // M400
  return st;
}

void ManeuverExecutor::position(double out_mm[4]) const {
  const planner::Vec4& p = interp_->state().logical_mm;
  for (int i = 0; i < 4; ++i) out_mm[i] = p[static_cast<size_t>(i)];
}

double ManeuverExecutor::corner_k(const Vec3& d_in, const Vec3& d_out) const {
  switch (speed_.profile) {
    case maneuver::SpeedProfile::constant: return 0.0;          // Eq. 63: no slow-down
    case maneuver::SpeedProfile::every_transition: return 1.0;  // Skjetne et al.: at every waypoint
    case maneuver::SpeedProfile::sharp_corner:
    case maneuver::SpeedProfile::sharp_corner_arc: break;
  }
  const Vec3 a = d_in.normalized(), b = d_out.normalized();
  return planner::sharp_corner_k(planner::corner_angle_deg(a.data(), b.data()), speed_.params.sharp);  // Eq. 64-66
}

void ManeuverExecutor::emit(const StreamWaypoint& w) {
  while (!queue_.try_push(w)) {
    release();  // a full queue: the servo must take what is there to make room
    if (cancel_ != nullptr && cancel_->load()) return;
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  pushed_mm_.store(pushed_mm_.load(std::memory_order_relaxed) + (w.p_m - last_.p_m).norm() * 1e3,
                   std::memory_order_relaxed);
  last_ = w;
  pushed_.fetch_add(1, std::memory_order_release);
}

void ManeuverExecutor::on_move(const planner::PlannedMove& m) {
  moves_.fetch_add(1, std::memory_order_relaxed);
  const Vec3 a = xyz_m(m.start_mm), b = xyz_m(m.end_mm);
  const Vec3 d = b - a;
  if (!m.kinematic || d.norm() < kMinSegmentM) {  // E only: the extruder position at the newest waypoint
    StreamWaypoint w = last_;
    w.e_mm = m.end_mm[3];
    w.k_prev = -1.0;
    emit(w);  // same position: an update
    return;
  }
  if ((a - last_.p_m).norm() > 1e-6) {  // the path jumps (e.g. a position reset): connect, from a stop
    emit(StreamWaypoint{a, 1.0, m.start_mm[3], m.line});
    last_dir_ = Vec3::Zero();
  }
  // The end of the move, a stop until the next move says otherwise; with it the corner weight of
  // the waypoint before it, known now (Eq. 64-66).
  const double k_prev = last_dir_.squaredNorm() > 0.0 ? corner_k(last_dir_, d) : 1.0;
  emit(StreamWaypoint{b, 1.0, m.end_mm[3], m.line, k_prev});
  last_dir_ = d;
}

void ManeuverExecutor::on_event(const planner::PlannerEvent& e) {
  if (e.kind == planner::EventKind::moves_done) wait_done_ = true;
}

double ManeuverExecutor::buffered_mm() const {
  return pushed_mm_.load(std::memory_order_relaxed) - telemetry_.path_mm.load(std::memory_order_relaxed);
}

void ManeuverExecutor::idle_tick(const std::atomic<bool>& cancel) {
  cancel_ = &cancel;
  if (planner_.queued() == 0) return;
  // Release the lookahead's tail when the input pauses or before the machine runs dry (the
  // controller sets its own speed: a flush changes no waypoint, only when it is released).
  const bool quiet = std::chrono::steady_clock::now() - last_command_ >
                     std::chrono::duration<double>(options_.input_pause_flush_s);
  if (quiet || buffered_mm() < options_.lead_mm) planner_.flush();
  planner_queued_.store(planner_.queued());
  release();
}

void ManeuverExecutor::release_lookahead() {
  if (planner_.queued() == 0) return;
  planner_.flush();
  planner_queued_.store(planner_.queued());
  release();
}

bool ManeuverExecutor::motion_pending() const {
  return planner_queued_.load() > 0 || pushed_.load() != popped_.load() ||
         !telemetry_.holding.load(std::memory_order_relaxed);
}

// Virtual time runs on while enough path lies ahead of the extruder, or when the planner holds
// nothing back; never into a stop that is only there because the planner has not caught up.
// Virtual time therefore advances only while the servo's next period cannot depend on when the
// planner thread releases its next waypoint, which keeps virtual-time runs deterministic.
bool ManeuverExecutor::may_advance_virtual(bool planner_busy) const {
  if (waiting_.load()) return true;
  if (!need_more_.load()) return true;
  if (released_.load() > popped_.load()) return true;  // new waypoints: the next cycle takes them
  return !planner_busy && planner_queued_.load() == 0;
}

void ManeuverExecutor::wait_for_room(const std::atomic<bool>& cancel) {
  const double max_mm = options_.max_buffered_s * speed_.params.m_s_m_s * 1e3;
  while (!cancel.load() && buffered_mm() > max_mm) std::this_thread::sleep_for(std::chrono::microseconds(500));
}

void ManeuverExecutor::wait_motion_done(const std::atomic<bool>& cancel) {
  planner_.flush();
  planner_queued_.store(planner_.queued());
  release();
  struct Waiting {
    std::atomic<bool>& w;
    explicit Waiting(std::atomic<bool>& f) : w(f) { w = true; }
    ~Waiting() { w = false; }
  } waiting(waiting_);
  while (!cancel.load() && motion_pending()) std::this_thread::sleep_for(std::chrono::microseconds(500));
}

void ManeuverExecutor::motion_status(MachineStatus& s) const {
  s.moving = !telemetry_.holding.load(std::memory_order_relaxed);
  s.print_time_s = telemetry_.path_time_s.load(std::memory_order_relaxed);
  s.moves_planned = moves_.load(std::memory_order_relaxed);
  s.segments_queued = pushed_.load() - popped_.load();
  for (int i = 0; i < 3; ++i) s.encoder_mm[i] = telemetry_.pos_mm[i].load(std::memory_order_relaxed);
  s.encoder_mm[3] = telemetry_.e_mm.load(std::memory_order_relaxed);
  s.encoder_samples = telemetry_.cycles.load(std::memory_order_relaxed);
  if (telemetry_.faulted.load())
    std::snprintf(s.last_error, sizeof s.last_error,
                  "motion stopped: tracking error beyond control.max_following_error_mm");
}

// ---- servo thread --------------------------------------------------------------------------------

void ManeuverExecutor::stop_and_hold() {
  StreamWaypoint w;
  while (queue_.try_pop(w)) popped_.fetch_add(1, std::memory_order_release);
  window_.clear();
  window_.push(StreamWaypoint{x_.x1_m, 1.0, servo_.e_mm(), 0});
  servo_.start_at(window_.first());
}

void ManeuverExecutor::servo_cycle(int64_t now_ns, bool cancel) {
  // The plant ran with the voltages held since the last cycle (zero-order hold).
  // The first cycle counts one period too (the plant rested through it), so the path time does
  // not depend on whether the first waypoints came before the first cycle or after it.
  const double dt_s =
      started_ ? std::clamp(static_cast<double>(now_ns - last_ns_) * 1e-9, 0.0, 20.0 * period_s_) : period_s_;
  started_ = true;
  last_ns_ = now_ns;
  if (dt_s > 0.0) {
    const int sub = std::max(1, static_cast<int>(std::ceil(dt_s / options_.plant_substep_s - 1e-9)));
    for (int i = 0; i < sub; ++i) plant_.step_rk4(x_, w_v_, dt_s / sub);  // Eq. 19-20
  }
  if (cancel) stop_and_hold();
  StreamWaypoint w;
  const bool faulted = telemetry_.faulted.load(std::memory_order_relaxed);
  // Not holding any more once waypoints are taken, said before they are counted as taken: the
  // planner thread's M400 (motion_pending) reads popped_ and then holding, and must not see all
  // waypoints taken beside the holding flag of the last idle cycle (it returned with 1 of 50
  // segments entered, under the sanitizers' slower servo thread).
  const uint64_t released = released_.load(std::memory_order_acquire);
  if (popped_.load(std::memory_order_relaxed) < released) telemetry_.holding.store(false, std::memory_order_relaxed);
  while ((faulted || !window_.full()) && popped_.load(std::memory_order_relaxed) < released && queue_.try_pop(w)) {
    if (!faulted) window_.push(w, kMinSegmentM);  // after a fault nothing more is followed
    popped_.fetch_add(1, std::memory_order_release);
  }
  const bool was_holding = servo_.holding();
  w_v_ = servo_.update(x_, period_s_);  // the measured state in, voltages for the next period out
  window_.release_before(servo_.oldest_needed());

  const maneuver::TrackError err = servo_.error();
  const double z1 = servo_.last().z1_m.norm();
  if (z1 > max_following_error_m_ && !telemetry_.faulted.load(std::memory_order_relaxed)) {
    telemetry_.faulted.store(true);
    stop_and_hold();
    w_v_ = servo_.update(x_, period_s_);
  }
  if (!was_holding || !servo_.holding()) {
    telemetry_.path_time_s.store(telemetry_.path_time_s.load(std::memory_order_relaxed) + dt_s,
                                 std::memory_order_relaxed);
    telemetry_.iae_cross_track_mm_s.store(
        telemetry_.iae_cross_track_mm_s.load(std::memory_order_relaxed) + std::abs(err.cross_m) * 1e3 * dt_s,
        std::memory_order_relaxed);
  }
  store_max(telemetry_.max_cross_track_mm, std::abs(err.cross_m) * 1e3);
  store_max(telemetry_.max_error_mm, z1 * 1e3);
  store_max(telemetry_.max_voltage_v, std::max(std::abs(w_v_.x()), std::abs(w_v_.y())));
  for (int i = 0; i < 3; ++i) telemetry_.pos_mm[i].store(x_.x1_m[i] * 1e3, std::memory_order_relaxed);
  telemetry_.e_mm.store(servo_.e_mm(), std::memory_order_relaxed);
  telemetry_.path_mm.store(servo_.s_m() * 1e3, std::memory_order_relaxed);
  telemetry_.segments_entered.store(servo_.segments_entered(), std::memory_order_relaxed);
  telemetry_.holding.store(servo_.holding() && queue_.empty(), std::memory_order_relaxed);
  const uint64_t newest = window_.last();
  const bool none_released = popped_.load(std::memory_order_relaxed) >= released_.load(std::memory_order_acquire);
  need_more_.store(none_released && (servo_.holding() || servo_.segment() + 2 > newest ||
                                      (window_.s_m(newest) - servo_.s_m()) * 1e3 < options_.lead_mm),
                   std::memory_order_release);
  telemetry_.cycles.fetch_add(1, std::memory_order_relaxed);
}

Result<std::unique_ptr<CommandExecutor>> make_maneuver_executor(const config::MachineConfig& cfg) {
  auto ex = ManeuverExecutor::create(cfg);
  if (!ex.ok()) return ex.error();
  return std::unique_ptr<CommandExecutor>(std::move(ex.value()));
}

Result<ManeuverRunSummary> run_maneuver_virtual(const config::MachineConfig& cfg,
                                                const std::vector<std::string>& gcode_lines, double timeout_s) {
  auto made = ManeuverExecutor::create(cfg);
  if (!made.ok()) return made.error();
  ManeuverExecutor* ex = made.value().get();
  VirtualClock clock(kNsPerS);
  Machine m(machine_options(cfg), clock, std::move(made.value()));
  ManeuverRunSummary r;
  std::atomic<uint64_t> done{0};
  std::mutex error_mutex;
  m.set_done_callback([&](CommandDone d) {
    if (!d.status.ok()) {
      std::lock_guard lock(error_mutex);
      if (r.rejected++ == 0) r.first_error = d.status.error().to_string();
    }
    done.fetch_add(1);
  });
  if (Status st = m.start(); !st) return st.error();
  uint64_t ticket = 0;
  bool timed_out = false;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  for (size_t i = 0; i < gcode_lines.size() && !timed_out; ++i) {
    auto cmd = gcode::parse_line(gcode_lines[i], SourceLocation{"gcode", static_cast<int>(i) + 1, 0});
    if (!cmd.ok()) {
      std::lock_guard lock(error_mutex);
      if (r.rejected++ == 0) r.first_error = cmd.error().to_string();
      continue;
    }
    if (cmd.value().letter == 0) continue;  // blank or comment
    while (!m.try_submit(ticket + 1, cmd.value())) {
      if (std::chrono::steady_clock::now() > deadline) {
        timed_out = true;
        break;
      }
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    if (!timed_out) ++ticket;
  }
  auto m400 = gcode::parse_line("M400", SourceLocation{"gcode", 0, 0});
  while (!timed_out && m400.ok() && !m.try_submit(ticket + 1, m400.value()))
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  if (!timed_out) ++ticket;  // the closing M400 waits for the end of motion
  while (done.load() < ticket && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  timed_out = timed_out || done.load() < ticket;
  m.stop();
  if (timed_out) return Error{"the virtual-time run did not finish within " + std::to_string(timeout_s) + " s"};
  const ManeuverTelemetry& t = ex->telemetry();
  r.commands = ticket - 1;
  r.moves = ex->moves_planned();
  r.segments_entered = t.segments_entered.load();
  r.virtual_s = seconds_from_ns(clock.now_ns()) - 1.0;
  r.path_time_s = t.path_time_s.load();
  r.path_mm = t.path_mm.load();
  r.max_cross_track_mm = t.max_cross_track_mm.load();
  r.iae_cross_track_mm_s = t.iae_cross_track_mm_s.load();
  r.max_error_mm = t.max_error_mm.load();
  r.max_voltage_v = t.max_voltage_v.load();
  for (int i = 0; i < 3; ++i) r.end_mm[i] = t.pos_mm[i].load();
  r.faulted = t.faulted.load();
  return r;
}

}  // namespace feedloop::engine
