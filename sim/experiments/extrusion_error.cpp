// Extruded-volume error on the compliant extruder (see extrusion_error.hpp).
#include "sim/experiments/extrusion_error.hpp"

#include <algorithm>  // std::max, std::min
#include <cmath>      // std::abs, std::round
#include <memory>
#include <sstream>

#include "gcode/parser.hpp"
#include "planner/interpreter.hpp"
#include "planner/kinematics.hpp"
#include "planner/lookahead.hpp"
#include "planner/pressure_advance.hpp"
#include "planner/sampler.hpp"

namespace feedloop::sim {

namespace {

struct Collect final : planner::MoveSink {
  std::vector<planner::PlannedMove>* out = nullptr;
  void on_move(const planner::PlannedMove& m) override { out->push_back(m); }
};

// Window around a speed change of an extruding path in which the error counts as a corner's.
constexpr double kCornerBefore_s = 0.1, kCornerAfter_s = 0.5;

// Speed changes of the extruding path: the start of an extruding move whose predecessor was not an
// extruding move in the same direction, and the end of an extruding move followed by none.
std::vector<double> corner_times(const std::vector<planner::PlannedMove>& moves) {
  std::vector<double> t;
  for (size_t i = 0; i < moves.size(); ++i) {
    const planner::PlannedMove& m = moves[i];
    if (!planner::pressure_advance_applies(m)) continue;
    const planner::PlannedMove* prev = i > 0 ? &moves[i - 1] : nullptr;
    const bool joins = prev != nullptr && planner::pressure_advance_applies(*prev) &&
                       std::abs(prev->end_time_s() - m.start_time_s) < 1e-9;
    double cos_turn = -1.0;
    if (joins)
      cos_turn = prev->unit[0] * m.unit[0] + prev->unit[1] * m.unit[1] + prev->unit[2] * m.unit[2];
    if (!joins || cos_turn < 0.9962) t.push_back(m.start_time_s);  // a turn of more than 5 deg
    const planner::PlannedMove* next = i + 1 < moves.size() ? &moves[i + 1] : nullptr;
    if (next == nullptr || !planner::pressure_advance_applies(*next)) t.push_back(m.end_time_s());
  }
  return t;
}

}  // namespace

Result<PlannedPrint> plan_gcode(const std::string& text, const std::string& name,
                                const planner::PlannerConfig& cfg_in) {
  planner::PlannerConfig cfg = cfg_in;
  cfg.allow_moves_before_homing = true;
  PlannedPrint print;
  Collect sink;
  sink.out = &print.moves;
  const auto kin = planner::make_kinematics(cfg);
  planner::Planner planner(cfg, sink);
  planner::Interpreter interp(cfg, *kin, planner);
  std::istringstream in(text);
  std::string line;
  SourceLocation where{name, 0, 0};
  gcode::Command cmd;
  while (std::getline(in, line)) {
    ++where.line;
    if (Status st = gcode::parse_line(line, where, cmd); !st) return st.error();
    if (cmd.empty()) continue;
    if (Status st = interp.execute(cmd); !st) return st.error();
  }
  planner.flush();
  print.lines = where.line;
  for (const planner::PlannedMove& m : print.moves)
    if (planner::pressure_advance_applies(m)) print.extruding_path_mm += m.length_mm;
  return print;
}

ExtrusionResult run_extrusion(const PlannedPrint& print, const ExtrusionRunOptions& o) {
  ExtrusionResult r;
  const std::vector<planner::PlannedMove>& moves = print.moves;
  if (moves.empty()) return r;
  ExtruderPlant plant(o.plant);
  const double area = plant.filament_area_mm2();
  const bool advance = o.advance_s > 0.0;
  planner::PressureAdvance pa(advance ? moves.size() * 7 + 8 : 8);
  const double e0 = moves.front().start_mm[planner::kE];
  if (advance) {
    pa.restart(e0, o.smooth_time_s);
    for (planner::PlannedMove m : moves) {
      m.pressure_advance_s = o.advance_s;
      m.pressure_advance_smooth_time_s = o.smooth_time_s;
      pa.push(m);
    }
  }
  const double h = advance ? pa.half_window_s() : 0.0;
  const std::vector<double> corners = corner_times(moves);
  r.corners = static_cast<int>(corners.size());

  size_t cursor = 0;  // the move covering (or next after) t
  // Nominal E and the commanded deposition rate at t.
  auto nominal = [&](double t, double& e_mm, double& q_cmd) {
    while (cursor + 1 < moves.size() && moves[cursor].end_time_s() <= t) ++cursor;
    const planner::PlannedMove& m = moves[cursor];
    q_cmd = 0.0;
    if (t < m.start_time_s) {  // before the first move or in a gap: at rest
      e_mm = cursor == 0 ? e0 : moves[cursor - 1].end_mm[planner::kE];
      return;
    }
    const planner::CartesianSample c = planner::sample_move(m, t);
    e_mm = c.pos_mm[planner::kE];
    if (t <= m.end_time_s() && planner::pressure_advance_applies(m))
      q_cmd = area * c.vel_mm_s[planner::kE];
  };
  auto quantise = [&](double e) {
    return o.steps_per_mm > 0.0 ? std::round(e * o.steps_per_mm) / o.steps_per_mm : e;
  };
  auto motor_at = [&](double t, double e_nominal) {
    return advance ? pa.position_mm(t) : e_nominal;
  };

  const double t_begin = moves.front().start_time_s - h - 0.01;
  const double t_end = moves.back().end_time_s() + h + o.tail_s;
  plant.reset(quantise(e0));
  size_t corner_i = 0;
  double e_nom = 0.0, q_cmd = 0.0;
  nominal(t_begin, e_nom, q_cmd);
  double motor_prev = motor_at(t_begin, e_nom);
  const auto steps = static_cast<long>((t_end - t_begin) / o.dt_s);
  for (long k = 1; k <= steps; ++k) {
    const double t = t_begin + static_cast<double>(k) * o.dt_s;
    double e_mid = 0.0, q_mid = 0.0;
    nominal(t - 0.5 * o.dt_s, e_mid, q_mid);
    nominal(t, e_nom, q_cmd);
    const double motor = motor_at(t, e_nom);
    r.max_motor_velocity_mm_s =
        std::max(r.max_motor_velocity_mm_s, std::abs(motor - motor_prev) / o.dt_s);
    motor_prev = motor;
    plant.step(quantise(motor), o.dt_s);
    const double err = std::abs(plant.nozzle_flow_mm3_s() - q_mid) * o.dt_s;
    r.error_mm3 += err;
    r.commanded_mm3 += q_mid * o.dt_s;
    const double tm = t - 0.5 * o.dt_s;
    while (corner_i < corners.size() && corners[corner_i] + kCornerAfter_s < tm) ++corner_i;
    if (corner_i < corners.size() && corners[corner_i] - kCornerBefore_s <= tm)
      r.corner_error_mm3 += err;
  }
  r.extruded_mm3 = plant.extruded_mm3();
  r.final_motor_mm = quantise(motor_prev);
  r.final_nominal_mm = quantise(moves.back().end_mm[planner::kE]);
  r.print_time_s = moves.back().end_time_s() - moves.front().start_time_s;
  return r;
}

}  // namespace feedloop::sim
