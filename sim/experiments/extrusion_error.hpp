// The extruded-volume error of a print on the compliant extruder (sim/extruder_plant.hpp), with
// and without pressure advance (planner/pressure_advance.hpp): the measure of
// docs/pressure_advance.md.
//
//   plan_gcode: the G-code through the interpreter and the lookahead (the daemon's planner).
//   run_extrusion: the extruder motor follows e(t) (K = 0) or e_adv(t), quantised to whole steps;
//     the plant turns it into nozzle flow; the error is
//       integral |q_noz(t) - q_cmd(t)| dt,  q_cmd = A_f * de/dt on extruding XY moves, 0 elsewhere
//     (what the slicer asked to be laid down on the path), over the whole print plus a settling
//     tail. In steady flow the error vanishes: it is made at corners and speed changes (and around
//     retractions). Also the error in the 0.5 s after every speed change on an extruding path
//     ("corners") and the largest e_adv velocity.
#pragma once

#include <string>
#include <vector>

#include "core/result.hpp"
#include "planner/config.hpp"
#include "planner/move.hpp"
#include "sim/extruder_plant.hpp"

namespace feedloop::sim {

struct PlannedPrint {
  std::vector<planner::PlannedMove> moves;
  double extruding_path_mm = 0.0;  // XY path length of the extruding moves
  int lines = 0;
};

// Plans G-code text (`name` for messages). Errors name the line.
Result<PlannedPrint> plan_gcode(const std::string& text, const std::string& name,
                                const planner::PlannerConfig& cfg);

struct ExtrusionRunOptions {
  double advance_s = 0.0;        // K (0: off, the motor follows e(t) exactly)
  double smooth_time_s = 0.040;  // Klipper's default
  double dt_s = 2e-4;            // plant step
  double steps_per_mm = 96.0;    // the motor moves in whole steps (0: continuous)
  double tail_s = 1.0;           // simulated after the last move
  ExtruderPlantParams plant;
};

struct ExtrusionResult {
  double error_mm3 = 0.0;         // integral |q_noz - q_cmd| dt
  double corner_error_mm3 = 0.0;  // the part within 0.5 s after a speed change of an extruding path
  double commanded_mm3 = 0.0;     // integral q_cmd dt
  double extruded_mm3 = 0.0;      // integral q_noz dt
  double max_motor_velocity_mm_s = 0.0;                 // |de_adv/dt| max
  double final_motor_mm = 0.0, final_nominal_mm = 0.0;  // where the motor ends (steps x mm/step)
  double print_time_s = 0.0;
  int corners = 0;
};

ExtrusionResult run_extrusion(const PlannedPrint& print, const ExtrusionRunOptions& options);

}  // namespace feedloop::sim
