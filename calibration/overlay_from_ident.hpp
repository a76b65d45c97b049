// From an identification (ident::identify_axis) to the calibration overlay's entry for that axis
// (config/calibration.hpp): the model the next print's feedforward uses, measured on the machine.
//
// What flows into the model (docs/calibration.md):
// - the fitted baseline (Eq. 13: m1, m2 as the fit fixed them, k1, k2, c1, c2);
// - the belt's position dependence kept from the config (Eq. 6: pulley distance L) but scaled so
//   that the direction-averaged K2 at the trace's mean carriage position is the fitted k2;
// - coulomb_friction: force and presliding deflection (the LPV feedforward's Dahl model).
// Every other named effect is recorded with its parameters and in_model: false.
#pragma once

#include <string>
#include <vector>

#include "config/calibration.hpp"
#include "ident/fit.hpp"

namespace feedloop::calibration {

// `current`: the config's model of that axis (its pulley distance is kept; nullptr: the thesis's
// 350 mm); `mean_position_mm`: the mean commanded position of the trace the fit used.
config::GantryModelConfig gantry_model_from_ident(const ident::IdentResult& r, const config::GantryModelConfig* current,
                                                  double mean_position_mm);

// Every named effect of r, with in_model set as above.
std::vector<config::CalibrationEffect> effects_from_ident(const ident::IdentResult& r);

// The overlay `existing` (an overlay file's text, "" for none) with r's axis replaced: what
// `feedloop ident fit --overlay` writes, so that fitting x then y leaves both in one file.
Result<std::string> merge_overlay(const config::MachineConfig& base, const std::string& existing_yaml,
                                  const std::string& existing_name, const ident::IdentResult& r,
                                  double mean_position_mm, const std::string& source);

}  // namespace feedloop::calibration
