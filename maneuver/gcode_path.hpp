// The XY(Z) waypoints of a print path from sliced G-code: the input of the maneuvering controller.
// Follows G0/G1 moves with G90/G91, M82/M83 and G92, and collects, per layer, the first loop of
// extruding moves (optionally only of one PrusaSlicer ";TYPE:" feature, e.g. "External perimeter").
// Layers are counted by the Z of extruding moves; `first_layer`, `layers` and `layer_stride` pick
// them (stride 2 on 0.2 mm layers gives 0.4 mm apart). The loops are joined in order, the join
// being the straight move from one loop's end to the next one's start. Waypoints are in mm
// (G-code units); scale to metres for PiecewiseLinearPath. G2/G3 arcs are taken as chords.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "core/result.hpp"
#include "maneuver/printer_model.hpp"

namespace feedloop::maneuver {

struct GcodePathOptions {
  size_t first_layer = 0;  // 0-based index among layers that have extruding moves
  size_t layers = 10;
  size_t layer_stride = 1;
  std::string feature;     // ";TYPE:" name to keep; empty keeps every extruding move
};

// Errors: a line that does not parse (with its location), or fewer layers than asked for.
Result<std::vector<Vec3>> extrusion_path_from_gcode(std::string_view text, const std::string& source,
                                                   const GcodePathOptions& options);
Result<std::vector<Vec3>> extrusion_path_from_gcode_file(const std::string& file,
                                                        const GcodePathOptions& options);

}  // namespace feedloop::maneuver
