// The factory of the model-based LPV feedforward (issue 5, "Feedforward") from the printer config:
// the gantry model (config model.gantry.x / y, thesis Eq. 13-16 with the belt of Eq. 6) for a
// Cartesian or CoreXY machine, the delta LPV model (config model.delta_lpv + delta geometry,
// delta paper Eq. 29) for a delta. Also the config -> model parameter mappings it uses.
#pragma once

#include <memory>

#include "config/machine_config.hpp"
#include "control/feedforward.hpp"
#include "control/feedforward/gantry_lpv.hpp"
#include "core/result.hpp"
#include "model/delta_params.hpp"
#include "model/gantry_axis.hpp"

namespace feedloop::control {

// model.gantry.<axis> -> Eq. 13 parameters (e = stepper.belt_efficiency).
model::GantryAxisParams gantry_params_from_config(const config::GantryModelConfig& g);
// model.delta_lpv + delta geometry -> the delta paper's parameters.
model::DeltaParams delta_params_from_config(const config::DeltaLpvConfig& c, const config::DeltaGeometryConfig& g);

// P = round(lpv.preview_ms / period). Errors: a config without the model section its kinematics
// needs (model.gantry.x and .y; model.delta_lpv and delta), a preview shorter than 2 periods,
// a bad period, a model the design rejects. freeze_at_centre (delta only): the fixed centre model.
// With feedforward.lpv.jump_accel_mm_s2 > 0 the inverse sits behind a VelocityJumpSmoother
// (velocity_jump_smoother.hpp): its preview grows by the jump window.
Result<std::unique_ptr<Feedforward>> make_model_feedforward(const config::MachineConfig& cfg, double period_s,
                                                           bool freeze_at_centre = false);

}  // namespace feedloop::control
