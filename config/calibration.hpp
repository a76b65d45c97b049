// Calibration overlays: the model a calibration measured on the machine, laid over the printer's
// config so that the next print's feedforward uses it (issue 15: "every named effect flows back
// into the model"). An overlay is a small YAML file in the config's own shape:
//
//   calibration_version: 1
//   source: "feedloop ident fit, trace cal_x.csv, axis x"     # what measured it (free text)
//   model:
//     gantry:
//       x: {k1_n_per_m: 298000, k2_n_per_m: 121000, coulomb_friction_n: 2.1, ...}
//   control:                                                   # optional: the PI gains chosen
//     axes:                                                    # on the calibrated model
//       x: {kp: 0.25, ki_per_s: 10}
//   effects:                                                   # what the identification named
//     - {axis: x, name: coulomb_friction, params: {force_n: 2.1}, in_model: true}
//
// `model.gantry.<axis>` takes any key of the config's `model.gantry.<axis>` (config/README.md)
// and replaces only the keys it names; an axis the config has no model for needs all six Eq. 13
// parameters. `control.axes.<axis>` sets that axis's PI gains (kp, ki_per_s), as the config's
// `control.axes` does; the others keep theirs. `effects` records every named effect with its
// parameters and whether the model carries it (`in_model`); it changes nothing. The overlay's
// problems are reported like a config's, every one with the overlay's file:line:column, and nothing
// is applied when any exists.
#pragma once

#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "config/machine_config.hpp"
#include "core/result.hpp"

namespace feedloop::config {

struct CalibrationEffect {
  std::string axis;
  std::string name;                       // ident vocabulary (DESIGN.md): coulomb_friction, ...
  std::map<std::string, double> params;  // in the vocabulary's units
  bool in_model = false;                  // the overlay's model carries it
};

struct Calibration {
  std::string source;
  std::vector<GantryModelConfig> gantry;  // written in full (every key of the entry)
  std::vector<CalibrationEffect> effects;
  std::vector<AxisGainsConfig> gains;  // control.axes: per-axis PI gains (none: the config's)
};

struct AppliedCalibration {
  MachineConfig config;
  std::string source;
  std::vector<std::string> changes;  // "model.gantry.x.k1_n_per_m: 354562 -> 298000", one per key
                                     // ("control.axes.x.kp: 0.5 -> 0.25" for the gains)
  std::vector<std::string> axes;     // the axes the overlay's model.gantry names
  std::vector<CalibrationEffect> effects;
  std::vector<AxisGainsConfig> gains;  // the overlay's control.axes entries, as it sets them
};

// Lays the overlay over `base` (validated as a config's model section is). Error: every problem.
Result<AppliedCalibration> apply_calibration_text(const MachineConfig& base, std::string_view yaml,
                                                  const std::string& source_name);
Result<AppliedCalibration> apply_calibration_file(const MachineConfig& base, const std::string& path);

// The overlay's YAML; apply_calibration_text of it sets every written key exactly.
std::string calibration_yaml(const Calibration& c);

}  // namespace feedloop::config
