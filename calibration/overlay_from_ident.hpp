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

// The belt is the one identification fitted: uniform at the fitted k2 (belt_unit_stiffness_n 0),
// with the named direction_dependent_stiffness's ratio as belt_direction_ratio (1 when none is
// named). The config's Eq. 6 geometry is an assumption the fit does not test.
// `current`: the config's model of that axis (what the fit does not give is kept; nullptr: the
// defaults).
config::GantryModelConfig gantry_model_from_ident(const ident::IdentResult& r,
                                                  const config::GantryModelConfig* current);
// The ratio the overlay writes as belt_direction_ratio: m's direction_dependent_stiffness ratio
// when it is named (and within the config's 0.1-10), else 1.
double direction_ratio_in_model(const ident::AxisModel& m);
// The scale the overlay writes as travel_scale: m's scale_error scale when it is named (and within
// 5 % of 1), else 1.
double travel_scale_in_model(const ident::AxisModel& m);

// Every named effect of r, with in_model set as above.
std::vector<config::CalibrationEffect> effects_from_ident(const ident::IdentResult& r);

// The named effects that `feedloop calibrate` puts in the model only when the machine tracks its
// check pattern better with them: a periodic position error and an extra mode. Identification is
// asked for the model without them too (ident::FitOptions::not_carried, IdentResult::carried),
// which calibrate installs first; the model with them (IdentResult::augmented) is then tried on the
// check pattern. A mode of another structure than the model's (the second simulator's distributed
// belt: its clean seed 2 names a mode on Y) tracked 0.0077 mm with it against 0.0041 without; a
// mass on the carriage (its extra_resonance draws) 0.0055 / 0.0054 against 0.0064 / 0.0067. A
// periodic error named beside a backlash (its backlash draw 1, Y: 8.9 um at 2.08 mm, in no part of
// that machine) tracked the thesis's large star 0.0136 mm with it against 0.0094 without.
const std::vector<ident::Effect>& effects_tried_on_the_machine();
// r with its augmented model replaced by the carried one: what merge_overlay is given.
ident::IdentResult with_carried_model(const ident::IdentResult& r);

// The overlay `existing` (an overlay file's text, "" for none) with r's axis replaced: what
// `feedloop ident fit --overlay` writes, so that fitting x then y leaves both in one file.
Result<std::string> merge_overlay(const config::MachineConfig& base,
                                  const std::string& existing_yaml,
                                  const std::string& existing_name, const ident::IdentResult& r,
                                  const std::string& source);

// The overlay `yaml` with its control.axes gains replaced by `gains` (empty: none, the config's
// gains apply): what `feedloop calibrate` installs after choosing the PI gains on the calibrated
// model.
Result<std::string> overlay_with_gains(const config::MachineConfig& base, const std::string& yaml,
                                       const std::string& name,
                                       const std::vector<config::AxisGainsConfig>& gains);

// The overlay `yaml` with one size of `axis`'s model (`size`: a member of GantryModelConfig, e.g.
// &GantryModelConfig::coulomb_friction_n) multiplied by `scale`, everything else as it is: what
// `feedloop calibrate` tries on the check pattern when the machine's friction or dead band may
// follow another law than the identification's (a Dahl bristle, a sharp dead band). Error: the
// overlay has no model of that axis, or the scaled size is out of the config's range.
Result<std::string> overlay_with_size_scaled(const config::MachineConfig& base,
                                             const std::string& yaml, const std::string& name,
                                             const std::string& axis,
                                             double config::GantryModelConfig::*size, double scale);

}  // namespace feedloop::calibration
