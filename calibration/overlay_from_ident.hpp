// From an identification (ident::identify_axis) to the calibration overlay's entry for that axis
// (config/calibration.hpp): the model the next print's feedforward uses, measured on the machine.
//
// What flows into the model (docs/calibration.md):
// - the fitted baseline (Eq. 13: m1, m2 as the fit fixed them, k1, k2, c1, c2);
// - the belt's position dependence (Eq. 6): its length L from direction_dependent_stiffness when
//   named (K2(+) / K2(-) = (L + x) / (L - x) at the trace's mean position x), else the config's;
//   k_hat scaled so that the direction-averaged K2 there is the fitted k2;
// - coulomb_friction: force and presliding deflection (the LPV feedforward's Dahl model);
// - backlash: its width (the LPV feedforward crosses the dead band ahead of each force reversal).
// Every other named effect is recorded with its parameters and in_model: false.
#pragma once

#include <string>
#include <vector>

#include "config/calibration.hpp"
#include "ident/fit.hpp"

namespace feedloop::calibration {

// Raises c1 and c2 so that each spring's own mode (the rotor on k1, the carriage on k2) has a
// damping ratio of at least zeta_min: the feedforward inverts the model, and a fit that puts a
// damping near zero (c1 on its bound: a 700 Hz rotor mode at zeta 0.002 on the second simulator)
// gives an inverse whose gain at that mode asks the motor for more steps than a link can carry.
// True when it raised one.
bool apply_damping_floor(config::GantryModelConfig& g, double zeta_min = 0.05);

// L (mm) from a direction ratio measured at mean_position_mm, or 0 when the model cannot use it
// (no ratio, or L not beyond the travel's largest |x| by 5 %).
double belt_length_from_direction_ratio(double ratio, double mean_position_mm,
                                        double max_abs_position_mm);

// The belt: Eq. 6 with L from the direction ratio when direction_dependent_stiffness is named
// and gives a belt beyond the travel; uniform at the fitted k2 (belt_unit_stiffness_n 0) when it
// is not named; otherwise the config's L, its k-hat scaled to the fitted k2.
// `current`: the config's model of that axis (what the fit does not give is kept; nullptr: the
// defaults); `mean_position_mm`: the mean commanded position of the trace the fit used;
// `max_abs_position_mm`: the axis's travel, the largest |x|.
config::GantryModelConfig gantry_model_from_ident(const ident::IdentResult& r,
                                                  const config::GantryModelConfig* current,
                                                  double mean_position_mm,
                                                  double max_abs_position_mm);

// Every named effect of r, with in_model set as above.
std::vector<config::CalibrationEffect> effects_from_ident(const ident::IdentResult& r,
                                                          double mean_position_mm,
                                                          double max_abs_position_mm);

// The named effects the feedforward does not carry (recorded in the overlay with in_model false):
// runout, an extra mode, a scale error. Identification is asked for the model without them
// (ident::FitOptions::not_carried), and that model (IdentResult::carried) is what the overlay
// writes: on the second simulator's seed 5 a 45 Hz and a 29 Hz "resonance" at the damping bound
// were named, and the baseline fitted beside them tracked the check pattern 0.0109 mm with the
// feedforward alone where the baseline fitted without them tracked 0.0067.
const std::vector<ident::Effect>& effects_not_in_model();
// r with its augmented model replaced by the carried one: what merge_overlay is given.
ident::IdentResult with_carried_model(const ident::IdentResult& r);

// The overlay `existing` (an overlay file's text, "" for none) with r's axis replaced: what
// `feedloop ident fit --overlay` writes, so that fitting x then y leaves both in one file.
Result<std::string> merge_overlay(const config::MachineConfig& base, const std::string& existing_yaml,
                                  const std::string& existing_name, const ident::IdentResult& r,
                                  double mean_position_mm, const std::string& source);

// The overlay `yaml` with its control.axes gains replaced by `gains` (empty: none, the config's
// gains apply): what `feedloop calibrate` installs after choosing the PI gains on the calibrated
// model.
Result<std::string> overlay_with_gains(const config::MachineConfig& base, const std::string& yaml,
                                       const std::string& name,
                                       const std::vector<config::AxisGainsConfig>& gains);

}  // namespace feedloop::calibration
