// From the printer config (config/) to the parameter structs of control/ (DESIGN.md "Data flow":
// the config is read once, at the edge; control/ never includes config/). One place for every
// config -> control mapping: PI gains, lost-step detector, encoder guard, input shaper, and the
// model-based LPV feedforward (the gantry model of config model.gantry.x / y, thesis Eq. 13-16
// with the belt of Eq. 6, for a Cartesian or CoreXY machine; the delta LPV model of config
// model.delta_lpv + delta geometry, delta paper Eq. 29, for a delta).
#pragma once

#include <memory>
#include <string>

#include "config/machine_config.hpp"
#include "control/encoder_guard.hpp"
#include "control/feedforward.hpp"
#include "control/input_shaper.hpp"
#include "control/lost_step_detector.hpp"
#include "control/pi_controller.hpp"
#include "core/result.hpp"
#include "model/delta_params.hpp"
#include "model/gantry_axis.hpp"
#include "planner/kinematics.hpp"

namespace feedloop::engine {

// The PI parameters of the config for one axis (joint) name: its control.axes gains, else the
// common ones (ControlConfig has no integral limit: PiParams's default).
control::PiParams pi_params_from_config(const config::ControlConfig& control,
                                        const std::string& axis, double period_s);

// threshold from ControlConfig::skipped_step_threshold_mm; full_step_mm = 1 / steps_per_mm x
// microsteps (the caller knows the driver's microstepping), 0 if unknown.
control::LostStepParams lost_step_params_from_config(const config::ControlConfig& control,
                                                     double full_step_mm);

// The encoder plausibility of one joint, for the host's guard and the device loop alike: no
// carriage moves faster than twice its axis's max_velocity_mm_s (the planner's limit for a joint
// without an axis section: a delta carriage), ringing included; beyond that travel in the time
// between two samples a sample may differ by control.max_encoder_jump_mm (noise, quantisation);
// three implausible samples in a row are the fault.
control::EncoderGuardParams encoder_guard_params_from_config(const config::MachineConfig& cfg,
                                                             const std::string& axis);

control::ShaperType shaper_type(config::ShaperType type);

// The setup the config asks for: X and Y shaped (ShaperConfig::for_axis("x"/"y")) through the
// kinematics' linear map, Z passed through; delta: carriages A, B, C shaped in joint space
// (for_axis("A"/"B"/"C"), falling back to the common values).
Result<control::InputShaperSetup> input_shaper_setup(const config::ShaperConfig& shaper,
                                                     const planner::Kinematics& kinematics,
                                                     double period_s);

// model.gantry.<axis> -> Eq. 13 parameters (e = stepper.belt_efficiency).
model::GantryAxisParams gantry_params_from_config(const config::GantryModelConfig& g);
// model.delta_lpv + delta geometry -> the delta paper's parameters.
model::DeltaParams delta_params_from_config(const config::DeltaLpvConfig& c,
                                            const config::DeltaGeometryConfig& g);

// The model-based LPV feedforward (control/feedforward/). P = round(lpv.preview_ms / period).
// Errors: a config without the model section its kinematics needs (model.gantry.x and .y;
// model.delta_lpv and delta), a preview shorter than 2 periods, a bad period, a model the design
// rejects. freeze_at_centre (delta only): the fixed centre model. With
// feedforward.lpv.jump_accel_mm_s2 > 0 the inverse sits behind a VelocityJumpSmoother
// (control/feedforward/velocity_jump_smoother.hpp): its preview grows by the jump window.
Result<std::unique_ptr<control::Feedforward>> make_model_feedforward(
    const config::MachineConfig& cfg, double period_s, bool freeze_at_centre = false);

}  // namespace feedloop::engine
